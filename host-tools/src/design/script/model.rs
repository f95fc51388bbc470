//! Script functions of the `Model` type: joining, moving, speed and arc changes, the
//! deformations (`deform_xyz`, `deform_cylinder` with script closures, and the built-in ones)
//! and the bitmap modulations (`modulate`, `globe`).

use super::args::{count, err, num, vec3_of, Opts, Res};
use super::points::{polar, pt, rotation, scaling};
use super::{describe, fn_label, Shared};
use crate::design::deform::{self, DeformError};
use crate::design::model::{Model, Step};
use crate::design::modulate::{self, Bitmap};
use crate::design::transform;
use glam::DVec3;
use rhai::{Dynamic, Engine, FnPtr, Map, NativeCallContext};
use std::sync::{Arc, Mutex};

fn call_vec3(ctx: &NativeCallContext, f: &FnPtr, p: DVec3) -> Result<DVec3, DeformError> {
    let r: Dynamic = f
        .call_within_context(ctx, (p.x, p.y, p.z))
        .map_err(|e| DeformError::Callback(format!("{}: {}", fn_label(f), describe(&e))))?;
    vec3_of(&r, fn_label(f)).map_err(|e| DeformError::Callback(describe(&e)))
}

fn call_value(ctx: &NativeCallContext, f: &FnPtr, v: f64, p: DVec3) -> Result<f64, DeformError> {
    let r: Dynamic = f
        .call_within_context(ctx, (v, p.x, p.y, p.z))
        .map_err(|e| DeformError::Callback(format!("{}: {}", fn_label(f), describe(&e))))?;
    num(&r, fn_label(f)).map_err(|e| DeformError::Callback(describe(&e)))
}

fn deform_script(
    ctx: &NativeCallContext,
    m: Model,
    fd: &FnPtr,
    fc: &FnPtr,
    fv: &FnPtr,
    tol: Option<f64>,
    cylinder: bool,
) -> Res<Model> {
    let mut d = |p: DVec3| call_vec3(ctx, fd, p);
    let mut c = |v: f64, p: DVec3| call_value(ctx, fc, v, p);
    let mut s = |v: f64, p: DVec3| call_value(ctx, fv, v, p);
    let r = if cylinder {
        deform::deform_cylinder_try(m, &mut d, &mut c, &mut s, tol)
    } else {
        deform::deform_xyz_try(m, &mut d, &mut c, &mut s, tol)
    };
    r.map_err(err)
}

pub(super) fn register_model(e: &mut Engine, shared: Arc<Mutex<Shared>>) {
    e.register_type_with_name::<Model>("Model");
    e.register_fn("model", Model::default);
    e.register_fn("then", |a: Model, b: Model| a.then(b));
    e.register_fn("+", |a: Model, b: Model| a.then(b));
    e.register_fn("string_count", |m: &mut Model| m.string_count() as i64);
    e.register_fn("volume", |m: &mut Model| m.volume_mm3());
    e.register_fn(
        "translate",
        |m: Model, x: Dynamic, y: Dynamic, z: Dynamic| -> Res<Model> {
            Ok(m.translate(DVec3::new(num(&x, "x")?, num(&y, "y")?, num(&z, "z")?)))
        },
    );
    e.register_fn(
        "set_axis",
        |m: &mut Model, x: Dynamic, y: Dynamic| -> Res<()> {
            m.axis_xy = [num(&x, "x")?, num(&y, "y")?];
            Ok(())
        },
    );
    e.register_fn("comment", |m: &mut Model, s: &str| {
        m.steps.insert(0, Step::Comment(s.to_string()))
    });
    e.register_fn("thin_at_emission", |m: Model, len: Dynamic| -> Res<Model> {
        Ok(m.thin_at_emission(num(&len, "length")?))
    });
    e.register_fn("arcs_to_lines", |m: Model, tol: Dynamic| -> Res<Model> {
        Ok(m.arcs_to_lines(num(&tol, "tolerance")?))
    });
    e.register_fn("scale_speed", |m: Model, k: Dynamic| -> Res<Model> {
        let k = num(&k, "factor")?;
        if !(k.is_finite() && k > 0.0) {
            return Err(format!("scale_speed: factor must be > 0, got {k}").into());
        }
        Ok(m.map_strings(|_, s| s.speed_mm_s *= k))
    });
    // `deform_xyz` and `deform_cylinder`, each without and with a chord tolerance.
    for (name, cylindrical) in [("deform_xyz", false), ("deform_cylinder", true)] {
        e.register_fn(
            name,
            move |ctx: NativeCallContext,
                  m: Model,
                  fd: FnPtr,
                  fc: FnPtr,
                  fv: FnPtr|
                  -> Res<Model> {
                deform_script(&ctx, m, &fd, &fc, &fv, None, cylindrical)
            },
        );
        e.register_fn(
            name,
            move |ctx: NativeCallContext,
                  m: Model,
                  fd: FnPtr,
                  fc: FnPtr,
                  fv: FnPtr,
                  tol: Dynamic|
                  -> Res<Model> {
                let tol = num(&tol, "tolerance")?;
                deform_script(&ctx, m, &fd, &fc, &fv, Some(tol), cylindrical)
            },
        );
    }
    e.register_fn("cup_to_dish", |m: Model| {
        deform::cup_to_dish(m, None).map_err(err)
    });
    e.register_fn("cup_to_dish", |m: Model, tol: Dynamic| -> Res<Model> {
        deform::cup_to_dish(m, Some(num(&tol, "tolerance")?)).map_err(err)
    });
    e.register_fn(
        "helix_to_sphere",
        |m: Model, r: Dynamic, h: Dynamic, z0: Dynamic| -> Res<Model> {
            deform::helix_to_sphere(m, num(&r, "R")?, num(&h, "H")?, num(&z0, "z0")?, None)
                .map_err(err)
        },
    );
    e.register_fn("heart_dish", |m: Model| {
        deform::heart_dish(m, None).map_err(err)
    });
    e.register_fn("heart_dish", |m: Model, tol: Dynamic| -> Res<Model> {
        deform::heart_dish(m, Some(num(&tol, "tolerance")?)).map_err(err)
    });
    e.register_fn("twisted_vase", |m: Model, o: Map| -> Res<Model> {
        let o = Opts::new(
            &o,
            "twisted_vase",
            &[
                "lobes",
                "amplitude",
                "twist",
                "bulge",
                "height",
                "tolerance",
            ],
        )?;
        let tol = o.f("tolerance", 0.0)?;
        deform::twisted_vase(
            m,
            o.f("lobes", 5.0)?,
            o.f("amplitude", 0.12)?,
            o.f("twist", 2.0)?,
            o.f("bulge", 0.25)?,
            o.f("height", 60.0)?,
            (tol > 0.0).then_some(tol),
        )
        .map_err(err)
    });
    let sh = shared.clone();
    e.register_fn(
        "modulate",
        move |m: Model, b: Bitmap, per_turn: Dynamic, contrast: Dynamic| -> Res<Model> {
            let (m, w) = modulate::modulate_helix(
                m,
                &b,
                count(&per_turn, "strings per turn")?,
                num(&contrast, "contrast")?,
            )
            .map_err(err)?;
            if let Ok(mut s) = sh.lock() {
                s.warnings.extend(w);
            }
            Ok(m)
        },
    );
    let sh = shared;
    e.register_fn("globe", move |b: Bitmap, o: Map| -> Res<Model> {
        let o = Opts::new(
            &o,
            "globe",
            &[
                "cx", "cy", "z0", "turns", "per_turn", "pitch", "cross", "speed", "contrast",
                "thin",
            ],
        )?;
        let d = modulate::Globe::default();
        let g = modulate::Globe {
            center_xy: [o.f("cx", d.center_xy[0])?, o.f("cy", d.center_xy[1])?],
            z0_mm: o.f("z0", d.z0_mm)?,
            turns: o.n("turns", d.turns)?,
            per_turn: o.n("per_turn", d.per_turn)?,
            pitch_mm: o.f("pitch", d.pitch_mm)?,
            cross_mm2: o.f("cross", d.cross_mm2)?,
            speed_mm_s: o.f("speed", d.speed_mm_s)?,
            contrast: o.f("contrast", d.contrast)?,
            thin_min_len_mm: o.f("thin", d.thin_min_len_mm)?,
        };
        let (m, w) = modulate::globe(&g, &b).map_err(err)?;
        if let Ok(mut s) = sh.lock() {
            s.warnings.extend(w);
        }
        Ok(m)
    });
}

pub(super) fn register_model_geometry(e: &mut Engine) {
    e.register_fn("moved", |m: Model, v: Dynamic| -> Res<Model> {
        Ok(m.translate(pt(&v, "vector")?))
    });
    e.register_fn("copies", |m: Model, v: Dynamic, n: Dynamic| -> Res<Model> {
        let (v, n) = (pt(&v, "vector")?, count(&n, "copies")?);
        if n == 0 || m.steps.len().saturating_mul(n) > crate::design::model::MAX_STRINGS {
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
    e.register_fn(
        "rotate_xy",
        |m: Model, c: Dynamic, angle: Dynamic| -> Res<Model> {
            transform::model(m, &rotation(&c, &angle)?).map_err(err)
        },
    );
    e.register_fn("scale", |m: Model, c: Dynamic, k: Dynamic| -> Res<Model> {
        transform::model(m, &scaling(&c, &k)?).map_err(err)
    });
    e.register_fn(
        "move_polar",
        |m: Model, c: Dynamic, r: Dynamic, angle: Dynamic| -> Res<Model> {
            transform::model(m, &polar(&c, &r, &angle)?).map_err(err)
        },
    );
    e.register_fn(
        "move_polar",
        |m: Model, c: Dynamic, r: Dynamic, angle: Dynamic, n: Dynamic| -> Res<Model> {
            transform::model_copies(&m, &polar(&c, &r, &angle)?, count(&n, "copies")?).map_err(err)
        },
    );
}
