//! Other tools' spellings: Kanada's `turtle.py` and Logo names registered as aliases, and the
//! hints that name the right function when a script calls one that does not exist here.

use super::args::{err, num, Res};
use crate::design::turtle::Turtle;
use rhai::{Dynamic, Engine};

/// Kanada's `turtle.py` spellings (and Logo's short ones) as aliases of the same functions.
pub(super) fn register_kanada(e: &mut Engine) {
    e.register_fn("setVelocity", |t: &mut Turtle, v: Dynamic| -> Res<()> {
        t.set_velocity(num(&v, "velocity")?).map_err(err)
    });
    e.register_fn("setCrossSection", |t: &mut Turtle, c: Dynamic| -> Res<()> {
        t.set_cross_section(num(&c, "cross-section")?).map_err(err)
    });
    e.register_fn("setHeading", |t: &mut Turtle, a: Dynamic| -> Res<()> {
        t.set_heading(num(&a, "heading")?).map_err(err)
    });
    for name in ["penup", "pu", "penUp"] {
        e.register_fn(name, |t: &mut Turtle| t.pen_up());
    }
    for name in ["pendown", "pd", "penDown"] {
        e.register_fn(name, |t: &mut Turtle| t.pen_down());
    }
    e.register_fn("fd", |t: &mut Turtle, r: Dynamic| -> Res<()> {
        t.forward(num(&r, "forward")?, 0.0).map_err(err)
    });
    e.register_fn("fd", |t: &mut Turtle, r: Dynamic, dz: Dynamic| -> Res<()> {
        t.forward(num(&r, "forward")?, num(&dz, "dz")?).map_err(err)
    });
    e.register_fn("lt", |t: &mut Turtle, a: Dynamic| -> Res<()> {
        t.left(num(&a, "left")?).map_err(err)
    });
    e.register_fn("rt", |t: &mut Turtle, a: Dynamic| -> Res<()> {
        t.right(num(&a, "right")?).map_err(err)
    });
}

/// Names from FullControl, Kanada's `turtle.py` and Logo that are spelt differently here.
const RENAMED: &[(&str, &str)] = &[
    ("arcXY", "arc_xy"),
    ("variable_arcXY", "variable_arc_xy"),
    ("circleXY", "circle_xy"),
    ("polygonXY", "polygon_xy"),
    ("rectangleXY", "rectangle_xy"),
    ("spiralXY", "spiral_xy"),
    ("helixZ", "helix_z"),
    ("sinewaveXYpolar", "sine_wave_xy"),
    ("squarewaveXYpolar", "square_wave_xy"),
    ("trianglewaveXYpolar", "triangle_wave_xy"),
    ("segmented_path", "subdivide"),
    ("move", "move_points (a path) or moved (a Model)"),
    ("reflectXY", "reflect_xy"),
    ("Point", "point"),
    ("Fan", "fan"),
    ("Hotend", "hotend"),
    ("Buildplate", "bed"),
    ("ManualGcode", "gcode"),
    ("ExtrusionGeometry", "set_extrusion"),
    ("Printer", "set_speed"),
    ("Extruder", "pen_up / pen_down (or extrude_to / travel_to)"),
    ("speed", "set_velocity"),
    ("setposition", "move_to"),
    ("setpos", "move_to"),
    ("turn", "left / right"),
    ("forward_to", "extrude_to"),
    ("set_fan", "fan (percent)"),
    ("setFan", "fan (percent)"),
    ("fan_speed", "fan (percent)"),
    (
        "arc",
        "arc_xy (a path of points) or extrude_arc (a true arc from the pen)",
    ),
    (
        "rotate",
        "rotate_xy(centre, angle in radians) for paths and models; left / right turn the turtle",
    ),
    ("rotateXY", "rotate_xy"),
    ("mirror", "reflect_xy"),
    ("mirrorXY", "reflect_xy"),
    ("scaleXY", "scale(centre, factor or [kx, ky, kz])"),
    ("travel_speed", "set_travel_speed"),
    ("setTravelSpeed", "set_travel_speed"),
    ("print_speed", "set_speed"),
    (
        "primer",
        "set_primer (\"profile\" or \"none\", before the first move)",
    ),
    ("temperature", "hotend / bed"),
    ("nozzle_temp", "hotend"),
    ("bed_temp", "bed"),
    ("Retraction", "set_retraction"),
    ("PlotAnnotation", "annotate"),
];

fn normalise(name: &str) -> String {
    name.chars()
        .filter(|c| *c != '_')
        .flat_map(char::to_lowercase)
        .collect()
}

/// For a call of a function that does not exist (Rhai's signature `name (types)`), a hint
/// naming the function meant: a known rename, or a registered function spelt the same but
/// for case and underscores.
pub(super) fn hint(engine: &Engine, signature: &str) -> Option<String> {
    let name = signature
        .split(|c: char| c == '(' || c.is_whitespace())
        .next()
        .unwrap_or("")
        .trim();
    if name.is_empty() {
        return None;
    }
    if let Some((_, to)) = RENAMED.iter().find(|(from, _)| *from == name) {
        return Some(format!("`{name}` is called `{to}` here"));
    }
    if names_of(engine).iter().any(|n| n == name) {
        return Some(format!(
            "`{name}` exists but not for these arguments; see docs/design.md for its forms"
        ));
    }
    let want = normalise(name);
    let names = names_of(engine);
    if let Some(n) = names.iter().find(|n| normalise(n) == want) {
        return Some(format!("did you mean `{n}`?"));
    }
    // A slip of the keyboard: the one registered name within two edits (of names long
    // enough that two edits do not make another word).
    if want.chars().count() < 5 {
        return None;
    }
    let mut near: Vec<&String> = names
        .iter()
        .filter(|n| !n.starts_with(|c: char| !c.is_ascii_alphabetic()))
        .filter(|n| edits(&normalise(n), &want) <= 2)
        .collect();
    near.sort_by_key(|n| edits(&normalise(n), &want));
    match near.as_slice() {
        [] => None,
        [one] => Some(format!("did you mean `{one}`?")),
        [a, b, ..] if edits(&normalise(a), &want) < edits(&normalise(b), &want) => {
            Some(format!("did you mean `{a}`?"))
        }
        many => Some(format!(
            "did you mean one of {}?",
            many.iter()
                .take(4)
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// Levenshtein distance between two short names (characters).
fn edits(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

/// Names of every registered function, sorted, each once.
fn names_of(engine: &Engine) -> Vec<String> {
    let mut names: Vec<String> = engine
        .gen_fn_signatures(false)
        .into_iter()
        .filter_map(|s| s.split('(').next().map(|n| n.trim().to_string()))
        .collect();
    names.sort();
    names.dedup();
    names
}
