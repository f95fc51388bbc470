//! Script functions for building from points (FullControl's reach), state changes at any
//! point, model move/copy/reflect, Kanada's turtle names, and the hints that name the right
//! function when a script calls one that does not exist. A point is an array `[x, y, z]`; a
//! path is an array of points, so Rhai's own array functions (`+`, `reverse`, `map`,
//! `extract`...) work on paths.

use super::script::{arr3, count, err, num, vec3_of, Opts, Res};
use crate::design::model::Model;
use crate::design::pen::AreaModel;
use crate::design::points::{self, PointsError};
use crate::design::profile::Retraction;
use crate::design::turtle::{Turtle, TurtleError};
use glam::DVec3;
use rhai::{Array, Dynamic, Engine, Map};

fn pt(d: &Dynamic, what: &str) -> Res<DVec3> {
    vec3_of(d, what)
}

fn path_of(a: &Array, what: &str) -> Res<Vec<DVec3>> {
    a.iter()
        .enumerate()
        .map(|(i, d)| pt(d, &format!("{what}: point {i}")))
        .collect()
}

fn array_of(ps: Result<Vec<DVec3>, PointsError>) -> Res<Array> {
    Ok(ps.map_err(err)?.into_iter().map(arr3).collect())
}

fn flag(d: &Dynamic, what: &str) -> Res<bool> {
    d.as_bool()
        .map_err(|t| format!("{what}: expected true/false, got {t}").into())
}

/// Registers everything in this module.
pub(super) fn register(e: &mut Engine) {
    register_points(e);
    register_pen(e);
    register_model_geometry(e);
    register_kanada(e);
}

fn register_points(e: &mut Engine) {
    e.register_fn(
        "point",
        |x: Dynamic, y: Dynamic, z: Dynamic| -> Res<Dynamic> {
            Ok(arr3(DVec3::new(
                num(&x, "x")?,
                num(&y, "y")?,
                num(&z, "z")?,
            )))
        },
    );
    for name in ["polar", "polar_to_point"] {
        e.register_fn(name, |c: Dynamic, r: Dynamic, a: Dynamic| -> Res<Dynamic> {
            Ok(arr3(points::polar(
                pt(&c, "centre")?,
                num(&r, "radius")?,
                num(&a, "angle")?,
            )))
        });
    }
    e.register_fn("point_to_polar", |p: Dynamic, o: Dynamic| -> Res<Map> {
        let (r, a) = points::to_polar(pt(&p, "point")?, pt(&o, "origin")?);
        let mut m = Map::new();
        m.insert("radius".into(), Dynamic::from_float(r));
        m.insert("angle".into(), Dynamic::from_float(a));
        Ok(m)
    });
    e.register_fn("distance", |a: Dynamic, b: Dynamic| -> Res<f64> {
        Ok(pt(&a, "a")?.distance(pt(&b, "b")?))
    });
    e.register_fn("midpoint", |a: Dynamic, b: Dynamic| -> Res<Dynamic> {
        Ok(arr3(pt(&a, "a")?.lerp(pt(&b, "b")?, 0.5)))
    });
    e.register_fn("path_length", |a: Array| -> Res<f64> {
        Ok(points::path_length(&path_of(&a, "path_length")?))
    });
    e.register_fn(
        "arc_xy",
        |c: Dynamic, r: Dynamic, a0: Dynamic, sweep: Dynamic, n: Dynamic| -> Res<Array> {
            array_of(points::arc_xy(
                pt(&c, "centre")?,
                num(&r, "radius")?,
                num(&a0, "start angle")?,
                num(&sweep, "sweep")?,
                count(&n, "segments")?,
            ))
        },
    );
    e.register_fn(
        "variable_arc_xy",
        |c: Dynamic,
         r: Dynamic,
         a0: Dynamic,
         sweep: Dynamic,
         n: Dynamic,
         dr: Dynamic,
         dz: Dynamic|
         -> Res<Array> {
            array_of(points::variable_arc_xy(
                pt(&c, "centre")?,
                num(&r, "radius")?,
                num(&a0, "start angle")?,
                num(&sweep, "sweep")?,
                count(&n, "segments")?,
                num(&dr, "radius change")?,
                num(&dz, "z change")?,
            ))
        },
    );
    // Closed shapes, counter-clockwise by default, with an optional trailing `cw` flag.
    type Shape = fn(&Dynamic, &Dynamic, &Dynamic, &Dynamic, bool) -> Res<Array>;
    let shapes: [(&str, Shape); 3] = [
        ("circle_xy", |c, r, a0, n, cw| {
            array_of(points::circle_xy(
                pt(c, "centre")?,
                num(r, "radius")?,
                num(a0, "start angle")?,
                count(n, "segments")?,
                cw,
            ))
        }),
        ("polygon_xy", |c, r, a0, n, cw| {
            array_of(points::polygon_xy(
                pt(c, "centre")?,
                num(r, "radius")?,
                num(a0, "start angle")?,
                count(n, "sides")?,
                cw,
            ))
        }),
        ("rectangle_xy", |s, x, y, _unused, cw| {
            array_of(points::rectangle_xy(
                pt(s, "start")?,
                num(x, "x size")?,
                num(y, "y size")?,
                cw,
            ))
        }),
    ];
    for (name, f) in shapes {
        if name == "rectangle_xy" {
            e.register_fn(name, move |s: Dynamic, x: Dynamic, y: Dynamic| {
                f(&s, &x, &y, &Dynamic::UNIT, false)
            });
            e.register_fn(
                name,
                move |s: Dynamic, x: Dynamic, y: Dynamic, cw: Dynamic| -> Res<Array> {
                    f(&s, &x, &y, &Dynamic::UNIT, flag(&cw, "cw")?)
                },
            );
        } else {
            e.register_fn(
                name,
                move |c: Dynamic, r: Dynamic, a0: Dynamic, n: Dynamic| f(&c, &r, &a0, &n, false),
            );
            e.register_fn(
                name,
                move |c: Dynamic, r: Dynamic, a0: Dynamic, n: Dynamic, cw: Dynamic| -> Res<Array> {
                    f(&c, &r, &a0, &n, flag(&cw, "cw")?)
                },
            );
        }
    }
    let spiral = |c: &Dynamic,
                  r0: &Dynamic,
                  r1: &Dynamic,
                  a0: &Dynamic,
                  t: &Dynamic,
                  n: &Dynamic,
                  cw: bool| {
        array_of(points::spiral_xy(
            pt(c, "centre")?,
            num(r0, "start radius")?,
            num(r1, "end radius")?,
            num(a0, "start angle")?,
            num(t, "turns")?,
            count(n, "segments")?,
            cw,
        ))
    };
    e.register_fn(
        "spiral_xy",
        move |c: Dynamic, r0: Dynamic, r1: Dynamic, a0: Dynamic, t: Dynamic, n: Dynamic| {
            spiral(&c, &r0, &r1, &a0, &t, &n, false)
        },
    );
    e.register_fn(
        "spiral_xy",
        move |c: Dynamic,
              r0: Dynamic,
              r1: Dynamic,
              a0: Dynamic,
              t: Dynamic,
              n: Dynamic,
              cw: Dynamic|
              -> Res<Array> { spiral(&c, &r0, &r1, &a0, &t, &n, flag(&cw, "cw")?) },
    );
    let helix = |a: [&Dynamic; 7], cw: bool| {
        array_of(points::helix_z(
            pt(a[0], "centre")?,
            num(a[1], "start radius")?,
            num(a[2], "end radius")?,
            num(a[3], "start angle")?,
            num(a[4], "turns")?,
            num(a[5], "pitch")?,
            count(a[6], "segments")?,
            cw,
        ))
    };
    e.register_fn(
        "helix_z",
        move |c: Dynamic,
              r0: Dynamic,
              r1: Dynamic,
              a0: Dynamic,
              t: Dynamic,
              pitch: Dynamic,
              n: Dynamic| { helix([&c, &r0, &r1, &a0, &t, &pitch, &n], false) },
    );
    e.register_fn(
        "helix_z",
        move |c: Dynamic,
              r0: Dynamic,
              r1: Dynamic,
              a0: Dynamic,
              t: Dynamic,
              pitch: Dynamic,
              n: Dynamic,
              cw: Dynamic|
              -> Res<Array> {
            helix([&c, &r0, &r1, &a0, &t, &pitch, &n], flag(&cw, "cw")?)
        },
    );
    let sine = |s: &Dynamic, a: &Dynamic, amp: &Dynamic, per: &Dynamic, n: &Dynamic, o: &Map| {
        let o = Opts::new(
            o,
            "sine_wave_xy",
            &["segments_per_period", "extra_half_period", "phase"],
        )?;
        array_of(points::sine_wave_xy(
            pt(s, "start")?,
            num(a, "direction angle")?,
            num(amp, "amplitude")?,
            num(per, "period")?,
            count(n, "periods")?,
            o.n("segments_per_period", 16)?,
            o.b("extra_half_period", false)?,
            o.f("phase", 0.0)?,
        ))
    };
    e.register_fn(
        "sine_wave_xy",
        move |s: Dynamic, a: Dynamic, amp: Dynamic, per: Dynamic, n: Dynamic| {
            sine(&s, &a, &amp, &per, &n, &Map::new())
        },
    );
    e.register_fn(
        "sine_wave_xy",
        move |s: Dynamic, a: Dynamic, amp: Dynamic, per: Dynamic, n: Dynamic, o: Map| {
            sine(&s, &a, &amp, &per, &n, &o)
        },
    );
    let square = |s: &Dynamic, a: &Dynamic, amp: &Dynamic, sp: &Dynamic, n: &Dynamic, x: bool| {
        array_of(points::square_wave_xy(
            pt(s, "start")?,
            num(a, "direction angle")?,
            num(amp, "amplitude")?,
            num(sp, "line spacing")?,
            count(n, "periods")?,
            x,
        ))
    };
    e.register_fn(
        "square_wave_xy",
        move |s: Dynamic, a: Dynamic, amp: Dynamic, sp: Dynamic, n: Dynamic| {
            square(&s, &a, &amp, &sp, &n, false)
        },
    );
    e.register_fn(
        "square_wave_xy",
        move |s: Dynamic,
              a: Dynamic,
              amp: Dynamic,
              sp: Dynamic,
              n: Dynamic,
              x: Dynamic|
              -> Res<Array> {
            square(&s, &a, &amp, &sp, &n, flag(&x, "extra_half_period")?)
        },
    );
    e.register_fn(
        "triangle_wave_xy",
        |s: Dynamic, a: Dynamic, amp: Dynamic, sp: Dynamic, n: Dynamic| -> Res<Array> {
            array_of(points::triangle_wave_xy(
                pt(&s, "start")?,
                num(&a, "direction angle")?,
                num(&amp, "amplitude")?,
                num(&sp, "tip spacing")?,
                count(&n, "periods")?,
            ))
        },
    );
    e.register_fn(
        "segmented_line",
        |a: Dynamic, b: Dynamic, n: Dynamic| -> Res<Array> {
            array_of(points::segmented_line(
                pt(&a, "start")?,
                pt(&b, "end")?,
                count(&n, "segments")?,
            ))
        },
    );
    e.register_fn("subdivide", |a: Array, max_len: Dynamic| -> Res<Array> {
        let p = path_of(&a, "subdivide")?;
        array_of(points::subdivide(&p, num(&max_len, "max length")?))
    });
    e.register_fn("move_points", |a: Array, v: Dynamic| -> Res<Array> {
        let p = path_of(&a, "move_points")?;
        Ok(points::moved(&p, pt(&v, "vector")?)
            .into_iter()
            .map(arr3)
            .collect())
    });
    e.register_fn(
        "copy_points",
        |a: Array, v: Dynamic, n: Dynamic| -> Res<Array> {
            let p = path_of(&a, "copy_points")?;
            array_of(points::copied(&p, pt(&v, "vector")?, count(&n, "copies")?))
        },
    );
    e.register_fn(
        "reflect_xy",
        |a: Array, p1: Dynamic, p2: Dynamic| -> Res<Array> {
            let (p1, p2) = (pt(&p1, "mirror point 1")?, pt(&p2, "mirror point 2")?);
            // One point ([x, y, z]) or a path of points.
            if a.len() == 3 && a.iter().all(|d| d.as_float().is_ok() || d.as_int().is_ok()) {
                let p = pt(&Dynamic::from_array(a), "point")?;
                let r = points::reflect_xy(p, p1, p2).map_err(err)?;
                return Ok(vec![
                    Dynamic::from_float(r.x),
                    Dynamic::from_float(r.y),
                    Dynamic::from_float(r.z),
                ]);
            }
            let p = path_of(&a, "reflect_xy")?;
            array_of(
                p.into_iter()
                    .map(|p| points::reflect_xy(p, p1, p2))
                    .collect(),
            )
        },
    );
}

/// Registers a pen move as `name(x, y, z)` and as `name(point)`.
fn register_move(
    e: &mut Engine,
    name: &'static str,
    go: fn(&mut Turtle, DVec3) -> Result<(), TurtleError>,
) {
    e.register_fn(
        name,
        move |t: &mut Turtle, x: Dynamic, y: Dynamic, z: Dynamic| -> Res<()> {
            go(t, DVec3::new(num(&x, "x")?, num(&y, "y")?, num(&z, "z")?)).map_err(err)
        },
    );
    e.register_fn(name, move |t: &mut Turtle, p: Dynamic| -> Res<()> {
        go(t, pt(&p, name)?).map_err(err)
    });
}

fn register_pen(e: &mut Engine) {
    e.register_fn("turtle", |p: Dynamic| -> Res<Turtle> {
        Ok(Turtle::at(pt(&p, "start")?, 0.2, 20.0))
    });
    register_move(e, "extrude_to", Turtle::extrude_to);
    register_move(e, "travel_to", Turtle::travel_to);
    register_move(e, "travel_straight_to", Turtle::travel_straight_to);
    e.register_fn(
        "extrude_arc",
        |t: &mut Turtle, c: Dynamic, sweep: Dynamic| -> Res<()> {
            let c = pt(&c, "centre")?;
            t.extrude_arc([c.x, c.y], num(&sweep, "sweep")?, 0.0)
                .map_err(err)
        },
    );
    e.register_fn(
        "extrude_arc",
        |t: &mut Turtle, c: Dynamic, sweep: Dynamic, dz: Dynamic| -> Res<()> {
            let c = pt(&c, "centre")?;
            t.extrude_arc([c.x, c.y], num(&sweep, "sweep")?, num(&dz, "dz")?)
                .map_err(err)
        },
    );
    e.register_fn("extrude_path", |t: &mut Turtle, a: Array| -> Res<()> {
        t.extrude_path(&path_of(&a, "extrude_path")?).map_err(err)
    });
    e.register_fn("polyline", |t: &mut Turtle, a: Array| -> Res<()> {
        t.polyline(&path_of(&a, "polyline")?).map_err(err)
    });
    e.register_fn("fan", |t: &mut Turtle, p: Dynamic| -> Res<()> {
        t.fan(num(&p, "fan percent")?).map_err(err)
    });
    for (name, is_bed) in [("hotend", false), ("bed", true)] {
        let set = move |t: &mut Turtle, c: &Dynamic, wait: bool| -> Res<()> {
            let c = num(c, name)?;
            if is_bed {
                t.bed(c, wait)
            } else {
                t.hotend(c, wait)
            }
            .map_err(err)
        };
        e.register_fn(name, move |t: &mut Turtle, c: Dynamic| set(t, &c, false));
        e.register_fn(
            name,
            move |t: &mut Turtle, c: Dynamic, w: Dynamic| -> Res<()> {
                set(t, &c, flag(&w, "wait")?)
            },
        );
    }
    e.register_fn("set_extrusion", |t: &mut Turtle, o: Map| -> Res<()> {
        let o = Opts::new(&o, "set_extrusion", &["width", "height", "area_model"])?;
        let model = match o_str(&o, "area_model")? {
            Some(s) => AreaModel::parse(&s).map_err(err)?,
            None => AreaModel::Rectangle,
        };
        t.set_extrusion(o.f("width", 0.4)?, o.f("height", 0.2)?, model)
            .map_err(err)
    });
    e.register_fn(
        "set_width_height",
        |t: &mut Turtle, w: Dynamic, h: Dynamic| -> Res<()> {
            t.set_extrusion(num(&w, "width")?, num(&h, "height")?, AreaModel::Rectangle)
                .map_err(err)
        },
    );
    e.register_fn("set_speed", |t: &mut Turtle, v: Dynamic| -> Res<()> {
        t.set_velocity(num(&v, "speed")?).map_err(err)
    });
    e.register_fn("set_retraction", |t: &mut Turtle, o: Map| -> Res<()> {
        let o = Opts::new(&o, "set_retraction", &["length", "speed", "min_travel"])?;
        t.set_retraction(Retraction {
            length_mm: o.f("length", 0.0)?,
            speed_mm_s: o.f("speed", 35.0)?,
            min_travel_mm: o.f("min_travel", 2.0)?,
        })
        .map_err(err)
    });
    e.register_fn("gcode", |t: &mut Turtle, s: &str| -> Res<()> {
        t.gcode(s).map_err(err)
    });
    e.register_fn("pause", |t: &mut Turtle| t.pause(false));
    e.register_fn("pause_now", |t: &mut Turtle| t.pause(true));
    e.register_get("position", |t: &mut Turtle| arr3(t.state().pos));
}

fn o_str(o: &Opts, key: &str) -> Res<Option<String>> {
    match o.get(key) {
        None => Ok(None),
        Some(d) => d
            .clone()
            .into_string()
            .map(Some)
            .map_err(|t| format!("{key}: expected a string, got {t}").into()),
    }
}

fn register_model_geometry(e: &mut Engine) {
    e.register_fn("moved", |m: Model, v: Dynamic| -> Res<Model> {
        Ok(m.translate(pt(&v, "vector")?))
    });
    e.register_fn("copies", |m: Model, v: Dynamic, n: Dynamic| -> Res<Model> {
        let (v, n) = (pt(&v, "vector")?, count(&n, "copies")?);
        if n == 0 || m.steps.len().saturating_mul(n) > crate::design::parts::MAX_PART_STRINGS {
            return Err(format!(
                "copies: 1.. copies of a {}-step model, got {n}",
                m.steps.len()
            )
            .into());
        }
        Ok(Model::assemble(
            (0..n).map(|k| m.clone().translate(v * k as f64)),
        ))
    });
    e.register_fn(
        "reflect_xy",
        |m: Model, p1: Dynamic, p2: Dynamic| -> Res<Model> {
            let (a, b) = (pt(&p1, "mirror point 1")?, pt(&p2, "mirror point 2")?);
            if (b - a).truncate().length_squared().is_nan()
                || (b - a).truncate().length_squared() <= 0.0
            {
                return Err(
                    "reflect_xy: the two points of the mirror line must differ in X or Y".into(),
                );
            }
            Ok(m.reflect_xy(a, b))
        },
    );
    e.register_fn("subdivide", |m: Model, max_len: Dynamic| -> Res<Model> {
        m.subdivide(num(&max_len, "max length")?).map_err(err)
    });
}

/// Kanada's `turtle.py` spellings (and Logo's short ones) as aliases of the same functions.
fn register_kanada(e: &mut Engine) {
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
    ("move_polar", "polar + move_points"),
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
    names_of(engine)
        .into_iter()
        .find(|n| normalise(n) == want)
        .map(|n| format!("did you mean `{n}`?"))
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
