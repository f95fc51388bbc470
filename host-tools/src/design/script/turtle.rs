//! Script functions of the `Turtle` (Kanada's interface): creating one, moving and turning,
//! pen and speed changes, the layer/turn marks, and its position getters.

use super::args::{err, num, vec3_of, Opts, Res};
use crate::design::init::InitOptions;
use crate::design::pen::AreaModel;
use crate::design::profile::{Primer, Profile};
use crate::design::turtle::Turtle;
use glam::DVec3;
use rhai::{Dynamic, Engine, Map};

/// The named `init`'s keys (FullControl's `initialization_data` names; speeds in mm/s).
const INIT_KEYS: &[&str] = &[
    "start",
    "nozzle_temp",
    "bed_temp",
    "fan_percent",
    "print_speed",
    "travel_speed",
    "extrusion_width",
    "extrusion_height",
    "area_model",
    "cross_section",
    "dia_feed",
    "primer",
];

fn init_options(o: &Map) -> Res<InitOptions> {
    let o = Opts::new(o, "init", INIT_KEYS)?;
    let f = |k: &str| -> Res<Option<f64>> {
        o.get(k).map(|d| num(d, &format!("init.{k}"))).transpose()
    };
    let s = |k: &str| -> Res<Option<String>> {
        o.get(k)
            .map(|d| {
                d.clone()
                    .into_string()
                    .map_err(|t| format!("init.{k}: expected a string, got {t}").into())
            })
            .transpose()
    };
    Ok(InitOptions {
        start: o
            .get("start")
            .map(|d| vec3_of(d, "init.start"))
            .transpose()?,
        nozzle_temp_c: f("nozzle_temp")?,
        bed_temp_c: f("bed_temp")?,
        fan_percent: f("fan_percent")?,
        print_speed_mm_s: f("print_speed")?,
        travel_speed_mm_s: f("travel_speed")?,
        width_mm: f("extrusion_width")?,
        height_mm: f("extrusion_height")?,
        area_model: match s("area_model")? {
            Some(m) => AreaModel::parse(&m).map_err(err)?,
            None => AreaModel::Rectangle,
        },
        cross_mm2: f("cross_section")?,
        filament_mm: f("dia_feed")?,
        primer: s("primer")?.map(|p| Primer::parse(&p)).transpose()?,
    })
}

pub(super) fn register_turtle(e: &mut Engine, profile: Profile) {
    e.register_type_with_name::<Turtle>("Turtle");
    // Shared by the constructors (each closure owns a handle).
    let profile = std::rc::Rc::new(profile);
    let p = profile.clone();
    e.register_fn("init", move |o: Map| -> Res<Turtle> {
        Turtle::init_with(&init_options(&o)?, &p).map_err(err)
    });
    let limits = profile.clone();
    e.register_fn(
        "init",
        move |fd: Dynamic,
              head: Dynamic,
              bed: Dynamic,
              c: Dynamic,
              x: Dynamic,
              y: Dynamic,
              z: Dynamic|
              -> Res<Turtle> {
            Turtle::init(
                num(&fd, "filament diameter")?,
                num(&head, "head temperature")?,
                num(&bed, "bed temperature")?,
                num(&c, "cross-section")?,
                num(&x, "x0")?,
                num(&y, "y0")?,
                num(&z, "z0")?,
            )
            .map(|t| t.with_speed_limit(&limits))
            .map_err(err)
        },
    );
    e.register_fn(
        "turtle",
        move |x: Dynamic, y: Dynamic, z: Dynamic| -> Res<Turtle> {
            Ok(Turtle::at(
                DVec3::new(num(&x, "x")?, num(&y, "y")?, num(&z, "z")?),
                0.2,
                20.0,
            )
            .with_speed_limit(&profile))
        },
    );
    e.register_fn("forward", |t: &mut Turtle, r: Dynamic| -> Res<()> {
        t.forward(num(&r, "forward")?, 0.0).map_err(err)
    });
    e.register_fn(
        "forward",
        |t: &mut Turtle, r: Dynamic, dz: Dynamic| -> Res<()> {
            t.forward(num(&r, "forward")?, num(&dz, "dz")?).map_err(err)
        },
    );
    e.register_fn("left", |t: &mut Turtle, a: Dynamic| -> Res<()> {
        t.left(num(&a, "left")?).map_err(err)
    });
    e.register_fn("right", |t: &mut Turtle, a: Dynamic| -> Res<()> {
        t.right(num(&a, "right")?).map_err(err)
    });
    e.register_fn("up", |t: &mut Turtle, d: Dynamic| -> Res<()> {
        t.up(num(&d, "up")?).map_err(err)
    });
    e.register_fn("down", |t: &mut Turtle, d: Dynamic| -> Res<()> {
        t.down(num(&d, "down")?).map_err(err)
    });
    e.register_fn("set_velocity", |t: &mut Turtle, v: Dynamic| -> Res<()> {
        t.set_velocity(num(&v, "velocity")?).map_err(err)
    });
    e.register_fn(
        "set_cross_section",
        |t: &mut Turtle, c: Dynamic| -> Res<()> {
            t.set_cross_section(num(&c, "cross-section")?).map_err(err)
        },
    );
    e.register_fn("set_heading", |t: &mut Turtle, a: Dynamic| -> Res<()> {
        t.set_heading(num(&a, "heading")?).map_err(err)
    });
    e.register_fn(
        "move_to",
        |t: &mut Turtle, x: Dynamic, y: Dynamic, z: Dynamic| -> Res<()> {
            t.goto(num(&x, "x")?, num(&y, "y")?, num(&z, "z")?)
                .map_err(err)
        },
    );
    e.register_fn("comment", |t: &mut Turtle, s: &str| t.comment(s));
    e.register_fn("pen_up", |t: &mut Turtle| t.pen_up());
    e.register_fn("pen_down", |t: &mut Turtle| t.pen_down());
    e.register_fn("push", |t: &mut Turtle| -> Res<()> {
        t.push().map_err(err)
    });
    e.register_fn("pop", |t: &mut Turtle| -> Res<()> { t.pop().map_err(err) });
    e.register_fn("mark_turn", |t: &mut Turtle, h: Dynamic| -> Res<()> {
        t.mark_turn(num(&h, "pitch")?);
        Ok(())
    });
    e.register_fn("mark_layer", |t: &mut Turtle, h: Dynamic| -> Res<()> {
        t.mark_layer(num(&h, "height")?);
        Ok(())
    });
    e.register_fn("model", |t: &mut Turtle| t.model().clone());
    e.register_get("x", |t: &mut Turtle| t.state().pos.x);
    e.register_get("y", |t: &mut Turtle| t.state().pos.y);
    e.register_get("z", |t: &mut Turtle| t.state().pos.z);
    e.register_get("heading", |t: &mut Turtle| t.state().heading_deg);
}
