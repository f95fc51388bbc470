//! Script functions that build ready-made parts: `helix`, `disc`, `cylinder`, and `vec3`.

use super::args::{err, num, Opts, Res};
use crate::design::model::Model;
use crate::design::parts::{self, Helix};
use rhai::{Array, Dynamic, Engine, Map};

fn helix_of(o: &Opts) -> Res<Helix> {
    let d = Helix::default();
    Ok(Helix {
        center_xy: [o.f("cx", d.center_xy[0])?, o.f("cy", d.center_xy[1])?],
        z0_mm: o.f("z0", d.z0_mm)?,
        radius_mm: o.f("radius", d.radius_mm)?,
        pitch_mm: o.f("pitch", d.pitch_mm)?,
        turns: o.f("turns", d.turns)?,
        per_turn: o.n("per_turn", d.per_turn)?,
        cross_mm2: o.f("cross", d.cross_mm2)?,
        speed_mm_s: o.f("speed", d.speed_mm_s)?,
        arcs: o.b("arcs", false)?,
        start_rad: o.f("start", 0.0)?.to_radians(),
    })
}

const HELIX_KEYS: &[&str] = &[
    "cx", "cy", "z0", "radius", "pitch", "turns", "per_turn", "cross", "speed", "arcs", "start",
];

pub(super) fn register_parts(e: &mut Engine) {
    e.register_fn("helix", |o: Map| -> Res<Model> {
        let o = Opts::new(&o, "helix", HELIX_KEYS)?;
        helix_of(&o)?.build().map_err(err)
    });
    e.register_fn("disc", |o: Map| -> Res<Model> {
        let o = Opts::new(
            &o,
            "disc",
            &[
                "cx", "cy", "z", "radius", "spacing", "seg", "cross", "speed",
            ],
        )?;
        parts::disc(
            [o.f("cx", 117.5)?, o.f("cy", 117.5)?],
            o.f("z", 0.2)?,
            o.f("radius", 10.0)?,
            o.f("spacing", 0.45)?,
            o.f("seg", 1.0)?,
            o.f("cross", 0.2)?,
            o.f("speed", 20.0)?,
        )
        .map_err(err)
    });
    e.register_fn("cylinder", |o: Map| -> Res<Model> {
        let o = Opts::new(
            &o,
            "cylinder",
            &[
                "cx", "cy", "z0", "radius", "height", "pitch", "per_turn", "cross", "speed",
            ],
        )?;
        parts::cylinder(
            [o.f("cx", 117.5)?, o.f("cy", 117.5)?],
            o.f("z0", 0.2)?,
            o.f("radius", 10.0)?,
            o.f("height", 10.0)?,
            o.f("pitch", 0.4)?,
            o.n("per_turn", 72)?,
            o.f("cross", 0.2)?,
            o.f("speed", 20.0)?,
        )
        .map_err(err)
    });
    e.register_fn("vec3", |x: Dynamic, y: Dynamic, z: Dynamic| -> Res<Array> {
        Ok(vec![
            Dynamic::from_float(num(&x, "x")?),
            Dynamic::from_float(num(&y, "y")?),
            Dynamic::from_float(num(&z, "z")?),
        ])
    });
}
