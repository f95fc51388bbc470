//! Script functions that drive the pen point by point: starting a turtle at a point, extruding
//! and travelling to points, arcs and along paths, and state changes at any point (fan,
//! temperatures, extrusion, speed, retraction, raw G-code, pauses).

use super::args::{arr3, err, num, Opts, Res};
use super::points::{flag, path_of, pt};
use crate::design::pen::AreaModel;
use crate::design::profile::{Primer, Profile, Retraction};
use crate::design::turtle::{Turtle, TurtleError};
use glam::DVec3;
use rhai::{Array, Dynamic, Engine, Map};

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

/// `profile`: the printer whose speed limits hold (speeds above them are refused as likely
/// mm/min values).
pub(super) fn register_pen(e: &mut Engine, profile: std::rc::Rc<Profile>) {
    e.register_fn("turtle", move |p: Dynamic| -> Res<Turtle> {
        Ok(Turtle::at(pt(&p, "start")?, 0.2, 20.0).with_speed_limit(&profile))
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
    e.register_fn(
        "set_travel_speed",
        |t: &mut Turtle, v: Dynamic| -> Res<()> {
            t.set_travel_speed(num(&v, "travel speed")?).map_err(err)
        },
    );
    e.register_fn("set_primer", |t: &mut Turtle, p: &str| -> Res<()> {
        t.set_primer(Primer::parse(p)?).map_err(err)
    });
    e.register_fn("annotate", |t: &mut Turtle, label: &str| -> Res<()> {
        t.annotate(None, label).map_err(err)
    });
    e.register_fn(
        "annotate",
        |t: &mut Turtle, p: Dynamic, label: &str| -> Res<()> {
            t.annotate(Some(pt(&p, "annotate")?), label).map_err(err)
        },
    );
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
