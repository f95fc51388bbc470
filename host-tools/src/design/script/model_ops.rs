//! Script functions that work on whole models beyond the basics: assembly, partitioning by a
//! predicate, splitting at markers, reordering, per-string changes, general modulation, the
//! bounding box and the printability checks.

use super::args::{arr3, count, err, num, Res};
use super::{fn_label, Shared};
use crate::design::checks::{self, CheckOptions};
use crate::design::deform;
use crate::design::model::{MarkerKind, Model, Step, Str};
use crate::design::modulate::{self, Bitmap};
use crate::design::profile::Profile;
use rhai::{Array, Dynamic, Engine, EvalAltResult, FnPtr, Map, NativeCallContext};
use std::sync::{Arc, Mutex};

/// The script's view of a string or travel, for `partition` predicates.
fn step_map(index: usize, s: &Step) -> Option<Map> {
    let mut m = Map::new();
    m.insert("index".into(), Dynamic::from_int(index as i64));
    match s {
        Step::String(st) => {
            m.insert("kind".into(), "string".into());
            m.insert("start".into(), arr3(st.start));
            m.insert("end".into(), arr3(st.end));
            m.insert("cross".into(), Dynamic::from_float(st.cross_mm2));
            m.insert("speed".into(), Dynamic::from_float(st.speed_mm_s));
        }
        Step::Travel { to, speed_mm_s } => {
            m.insert("kind".into(), "travel".into());
            m.insert("end".into(), arr3(*to));
            m.insert(
                "speed".into(),
                speed_mm_s.map_or(Dynamic::UNIT, Dynamic::from_float),
            );
        }
        _ => return None,
    }
    Some(m)
}

fn models_of(parts: Array, what: &str) -> Res<Vec<Model>> {
    parts
        .into_iter()
        .enumerate()
        .map(|(i, d)| {
            let t = d.type_name();
            d.try_cast::<Model>()
                .ok_or_else(|| format!("{what}: element {i} is a {t}, not a Model").into())
        })
        .collect()
}

/// Assembly, partitioning/reordering, general modulation and checks (the model operations
/// beyond `register_model`'s).
pub(super) fn register_model_ops(e: &mut Engine, shared: Arc<Mutex<Shared>>, profile: Profile) {
    e.register_fn("assemble", |parts: Array| -> Res<Model> {
        Ok(Model::assemble(models_of(parts, "assemble")?))
    });
    e.register_fn(
        "partition",
        |ctx: NativeCallContext, m: Model, pred: FnPtr| -> Res<Array> {
            let mut failure: Option<Box<EvalAltResult>> = None;
            let mut index = 0;
            let (yes, no) = m.partition(|s| {
                if failure.is_some() {
                    return false;
                }
                let Some(map) = step_map(index, s) else {
                    return false;
                };
                index += 1;
                let r: Res<Dynamic> = pred.call_within_context(&ctx, (map,));
                match r.and_then(|d| {
                    d.as_bool().map_err(|t| {
                        format!(
                            "partition: {} must return true or false, got {t}",
                            fn_label(&pred)
                        )
                        .into()
                    })
                }) {
                    Ok(b) => b,
                    Err(e) => {
                        failure = Some(e);
                        false
                    }
                }
            });
            match failure {
                Some(e) => Err(e),
                None => Ok(vec![Dynamic::from(yes), Dynamic::from(no)]),
            }
        },
    );
    e.register_fn("split_at_markers", |m: Model, kind: &str| -> Res<Array> {
        let kind = match kind {
            "turn" => MarkerKind::Turn,
            "layer" => MarkerKind::Layer,
            other => {
                return Err(format!(
                    "split_at_markers: kind is \"turn\" or \"layer\", got \"{other}\""
                )
                .into())
            }
        };
        Ok(m.split_at_markers(kind)
            .into_iter()
            .map(Dynamic::from)
            .collect())
    });
    e.register_fn(
        "reorder_parts",
        |parts: Array, order: Array| -> Res<Model> {
            let parts = models_of(parts, "reorder_parts")?;
            let order = order
                .iter()
                .map(|d| count(d, "reorder_parts: index"))
                .collect::<Res<Vec<usize>>>()?;
            Model::reorder_parts(parts, &order).map_err(|e| format!("reorder_parts: {e}").into())
        },
    );
    e.register_fn(
        "map_strings",
        |ctx: NativeCallContext, m: Model, f: FnPtr| -> Res<Model> {
            let mut failure: Option<Box<EvalAltResult>> = None;
            let m = m.map_strings(|i, s: &mut Str| {
                if failure.is_some() {
                    return;
                }
                let r: Res<Dynamic> =
                    f.call_within_context(&ctx, (i as i64, s.cross_mm2, s.speed_mm_s));
                let pair = r.and_then(|d| {
                    let a = d.into_array().map_err(|t| {
                        format!("{}: expected [cross, speed], got {t}", fn_label(&f))
                    })?;
                    match a.as_slice() {
                        [c, v] => Ok((num(c, "cross")?, num(v, "speed")?)),
                        _ => Err(format!("{}: expected [cross, speed]", fn_label(&f)).into()),
                    }
                });
                match pair {
                    Ok((c, v)) if c.is_finite() && c >= 0.0 && v.is_finite() && v > 0.0 => {
                        s.cross_mm2 = c;
                        s.speed_mm_s = v;
                    }
                    Ok((c, v)) => {
                        failure = Some(
                            format!("map_strings: string {i}: cross {c} / speed {v} invalid")
                                .into(),
                        )
                    }
                    Err(e) => failure = Some(e),
                }
            });
            match failure {
                Some(e) => Err(e),
                None => Ok(m),
            }
        },
    );
    let sh = shared;
    e.register_fn(
        "modulate_by",
        move |ctx: NativeCallContext,
              m: Model,
              b: Bitmap,
              contrast: Dynamic,
              f: FnPtr|
              -> Res<Model> {
            let mut failure: Option<Box<EvalAltResult>> = None;
            let r = modulate::modulate_by(m, &b, num(&contrast, "contrast")?, |i| {
                if failure.is_some() {
                    return None;
                }
                let r: Res<Dynamic> = f.call_within_context(&ctx, (i as i64,));
                let px = r.and_then(|d| {
                    if d.is_unit() {
                        return Ok(None);
                    }
                    let a = d
                        .into_array()
                        .map_err(|t| format!("{}: expected [x, y] or (), got {t}", fn_label(&f)))?;
                    match a.as_slice() {
                        [x, y] => Ok(Some((count(x, "x")?, count(y, "y")?))),
                        _ => Err(format!("{}: expected [x, y] or ()", fn_label(&f)).into()),
                    }
                });
                match px {
                    Ok(p) => p.map(|(x, y)| {
                        (
                            x.min(u32::MAX as usize) as u32,
                            y.min(u32::MAX as usize) as u32,
                        )
                    }),
                    Err(e) => {
                        failure = Some(e);
                        None
                    }
                }
            });
            if let Some(e) = failure {
                return Err(e);
            }
            let (m, w) = r.map_err(err)?;
            if let Ok(mut s) = sh.lock() {
                s.warnings.extend(w);
            }
            Ok(m)
        },
    );
    e.register_fn(
        "helix_to_sphere",
        |m: Model, r: Dynamic, h: Dynamic, z0: Dynamic, tol: Dynamic| -> Res<Model> {
            let tol = num(&tol, "tolerance")?;
            deform::helix_to_sphere(m, num(&r, "R")?, num(&h, "H")?, num(&z0, "z0")?, Some(tol))
                .map_err(err)
        },
    );
    e.register_fn("bbox", |m: &mut Model| -> Map {
        let b = m.bbox();
        let mut out = Map::new();
        if !b.is_empty() {
            out.insert("min".into(), arr3(b.min));
            out.insert("max".into(), arr3(b.max));
        }
        out
    });
    e.register_fn("check", move |m: &mut Model| -> Map {
        let rep = checks::check(m, &profile, &CheckOptions::default());
        let mut out = Map::new();
        out.insert("clean".into(), Dynamic::from_bool(rep.is_clean()));
        out.insert("total".into(), Dynamic::from_int(rep.total() as i64));
        let issues: Array = rep
            .issues
            .iter()
            .map(|i| {
                let mut m = Map::new();
                m.insert("kind".into(), i.kind.name().into());
                m.insert("step".into(), Dynamic::from_int(i.step as i64));
                m.insert("at".into(), arr3(i.at));
                m.insert("msg".into(), i.msg.clone().into());
                Dynamic::from_map(m)
            })
            .collect();
        out.insert("issues".into(), Dynamic::from_array(issues));
        out
    });
}
