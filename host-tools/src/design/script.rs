//! Design scripts in Rhai: a sandboxed, embedded language calling the same API as Rust code.
//!
//! The sandbox: no file or network access except reading PNG bitmaps next to the script
//! (`load_bitmap("map.png")`, no absolute paths, no `..`), no modules, and limits on
//! operations, call depth, string, array and map sizes. A script's last expression is the
//! design: a `Model` or a `Turtle` (its drawing). Errors carry the script line and column.
//!
//! See `docs/design.md` for the full list of functions; `host-tools/examples/*.rhai` use all
//! of them.

use crate::design::checks::{self, CheckOptions};
use crate::design::deform::{self, DeformError};
use crate::design::model::{MarkerKind, Model, Step, Str};
use crate::design::modulate::{self, Bitmap};
use crate::design::parts::{self, Helix};
use crate::design::profile::Profile;
use crate::design::turtle::Turtle;
use glam::DVec3;
use rhai::packages::{Package, StandardPackage};
use rhai::{Array, Dynamic, Engine, EvalAltResult, FnPtr, Map, NativeCallContext, Position, Scope};
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, Mutex};

pub(super) type Res<T> = Result<T, Box<EvalAltResult>>;

/// Limits of the sandbox.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Most operations one script may run.
    pub max_operations: u64,
    /// Deepest function call nesting.
    pub max_call_levels: usize,
    /// Longest string, bytes.
    pub max_string_size: usize,
    /// Largest array.
    pub max_array_size: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_operations: 200_000_000,
            max_call_levels: 64,
            max_string_size: 64 * 1024,
            max_array_size: 1_000_000,
        }
    }
}

/// A script error with its place in the script.
#[derive(Debug, thiserror::Error)]
#[error("{file}:{line}:{col}: {msg}")]
pub struct ScriptError {
    /// Script name (file name).
    pub file: String,
    /// 1-based line (0 when unknown).
    pub line: usize,
    /// 1-based column (0 when unknown).
    pub col: usize,
    /// Message.
    pub msg: String,
}

/// What a script produced.
#[derive(Debug)]
pub struct ScriptOutput {
    /// The design.
    pub model: Model,
    /// Warnings raised while building it (contrast too high, `warn(...)` calls).
    pub warnings: Vec<String>,
}

pub(super) fn num(d: &Dynamic, what: &str) -> Res<f64> {
    if let Ok(f) = d.as_float() {
        Ok(f)
    } else if let Ok(i) = d.as_int() {
        Ok(i as f64)
    } else {
        Err(format!("{what}: expected a number, got {}", d.type_name()).into())
    }
}

pub(super) fn count(d: &Dynamic, what: &str) -> Res<usize> {
    let v = num(d, what)?;
    if v.is_finite() && v >= 0.0 && v.fract() == 0.0 && v <= 1e9 {
        Ok(v as usize)
    } else {
        Err(format!("{what}: expected a whole number ≥ 0, got {v}").into())
    }
}

/// Reads options from a map with defaults, rejecting unknown keys.
pub(super) struct Opts<'a> {
    map: &'a Map,
    what: &'static str,
    known: &'static [&'static str],
}

impl<'a> Opts<'a> {
    pub(super) fn new(
        map: &'a Map,
        what: &'static str,
        known: &'static [&'static str],
    ) -> Res<Self> {
        for k in map.keys() {
            if !known.contains(&k.as_str()) {
                return Err(
                    format!("{what}: unknown option `{k}` (known: {})", known.join(", ")).into(),
                );
            }
        }
        Ok(Opts { map, what, known })
    }
    pub(super) fn f(&self, key: &str, default: f64) -> Res<f64> {
        debug_assert!(self.known.contains(&key));
        match self.map.get(key) {
            Some(d) => num(d, &format!("{}.{key}", self.what)),
            None => Ok(default),
        }
    }
    pub(super) fn n(&self, key: &str, default: usize) -> Res<usize> {
        match self.map.get(key) {
            Some(d) => count(d, &format!("{}.{key}", self.what)),
            None => Ok(default),
        }
    }
    pub(super) fn get(&self, key: &str) -> Option<&Dynamic> {
        debug_assert!(self.known.contains(&key));
        self.map.get(key)
    }
    pub(super) fn b(&self, key: &str, default: bool) -> Res<bool> {
        match self.map.get(key) {
            Some(d) => d
                .as_bool()
                .map_err(|t| format!("{}.{key}: expected true/false, got {t}", self.what).into()),
            None => Ok(default),
        }
    }
}

pub(super) fn vec3_of(d: &Dynamic, what: &str) -> Res<DVec3> {
    let arr = d
        .clone()
        .into_array()
        .map_err(|t| format!("{what}: expected an array [a, b, c], got {t}"))?;
    if arr.len() != 3 {
        return Err(format!("{what}: expected 3 numbers, got {}", arr.len()).into());
    }
    Ok(DVec3::new(
        num(&arr[0], what)?,
        num(&arr[1], what)?,
        num(&arr[2], what)?,
    ))
}

pub(super) fn err<E: std::fmt::Display>(e: E) -> Box<EvalAltResult> {
    e.to_string().into()
}

/// Shared state between the engine's callbacks and the caller.
#[derive(Default)]
struct Shared {
    warnings: Vec<String>,
}

/// Runs design scripts.
pub struct ScriptRunner {
    limits: Limits,
    profile: Profile,
    progress: Option<Arc<dyn Fn(u64) + Send + Sync>>,
}

impl ScriptRunner {
    /// A runner for `profile` (scripts see the bed) with default limits.
    pub fn new(profile: Profile) -> Self {
        ScriptRunner {
            limits: Limits::default(),
            profile,
            progress: None,
        }
    }

    /// Sets the sandbox limits.
    pub fn with_limits(mut self, limits: Limits) -> Self {
        self.limits = limits;
        self
    }

    /// Calls `f(operations)` now and then while a script runs (progress display).
    pub fn with_progress(mut self, f: impl Fn(u64) + Send + Sync + 'static) -> Self {
        self.progress = Some(Arc::new(f));
        self
    }

    /// Runs the script in `path`.
    pub fn run_file(&self, path: &Path) -> Result<ScriptOutput, ScriptError> {
        let name = path.display().to_string();
        let src =
            crate::fileio::read_text_bounded(path, crate::fileio::Limit::Script).map_err(|e| {
                ScriptError {
                    file: name.clone(),
                    line: 0,
                    col: 0,
                    msg: format!("cannot read: {e:#}"),
                }
            })?;
        let dir = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        self.run(&name, &src, &dir)
    }

    /// Runs `src` (named `name` in errors); bitmaps are read relative to `dir`.
    pub fn run(&self, name: &str, src: &str, dir: &Path) -> Result<ScriptOutput, ScriptError> {
        let shared = Arc::new(Mutex::new(Shared::default()));
        let engine = self.engine(dir, shared.clone());
        let at = |msg: String, pos: Position| ScriptError {
            file: name.to_string(),
            line: pos.line().unwrap_or(0),
            col: pos.position().unwrap_or(0),
            msg,
        };
        let ast = engine
            .compile(src)
            .map_err(|e| at(e.err_type().to_string(), e.position()))?;
        let mut scope = Scope::new();
        let c = self.profile.bed_center();
        scope.push_constant("BED_X", c[0]);
        scope.push_constant("BED_Y", c[1]);
        scope.push_constant(
            "BED_W",
            self.profile.bed.x_max_mm - self.profile.bed.x_min_mm,
        );
        scope.push_constant(
            "BED_D",
            self.profile.bed.y_max_mm - self.profile.bed.y_min_mm,
        );
        scope.push_constant("FILAMENT_D", self.profile.filament_diameter_mm);
        scope.push_constant("PI", std::f64::consts::PI);
        let result: Dynamic = engine.eval_ast_with_scope(&mut scope, &ast).map_err(|e| {
            let mut msg = describe(&e);
            if let Some(h) = not_found(&e).and_then(|sig| super::script_build::hint(&engine, sig)) {
                msg = format!("{msg} ({h})");
            }
            at(msg, innermost_position(&e))
        })?;
        let model = if result.is::<Model>() {
            result.cast::<Model>()
        } else if result.is::<Turtle>() {
            result.cast::<Turtle>().into_model()
        } else {
            return Err(at(
                format!(
                    "the script must end with a Model or a Turtle (its last expression), got {}",
                    result.type_name()
                ),
                last_line(src),
            ));
        };
        let warnings = shared
            .lock()
            .map(|mut s| std::mem::take(&mut s.warnings))
            .unwrap_or_default();
        Ok(ScriptOutput { model, warnings })
    }

    fn engine(&self, dir: &Path, shared: Arc<Mutex<Shared>>) -> Engine {
        let mut e = Engine::new_raw();
        e.register_global_module(StandardPackage::new().as_shared_module());
        // 0 would turn Rhai's operation limit off: the sandbox always keeps a limit.
        e.set_max_operations(self.limits.max_operations.max(1));
        e.set_max_call_levels(self.limits.max_call_levels);
        e.set_max_string_size(self.limits.max_string_size);
        e.set_max_array_size(self.limits.max_array_size);
        e.set_max_map_size(10_000);
        e.set_max_expr_depths(128, 64);
        e.on_print(|s| eprintln!("{s}"));
        e.on_debug(|s, _, pos| eprintln!("debug {pos}: {s}"));
        if let Some(p) = self.progress.clone() {
            e.on_progress(move |ops| {
                if ops % 1_000_000 == 0 {
                    p(ops);
                }
                None
            });
        }
        {
            let sh = shared.clone();
            e.register_fn("warn", move |msg: &str| {
                if let Ok(mut s) = sh.lock() {
                    s.warnings.push(msg.to_string());
                }
            });
        }
        register_turtle(&mut e);
        register_model(&mut e, shared.clone());
        register_model_ops(&mut e, shared, self.profile.clone());
        register_parts(&mut e);
        super::script_build::register(&mut e);
        let dir = dir.to_path_buf();
        e.register_type_with_name::<Bitmap>("Bitmap");
        e.register_fn("world_map", || Bitmap::world_map().map_err(err));
        e.register_fn("load_bitmap", move |rel: &str| -> Res<Bitmap> {
            let p = Path::new(rel);
            if p.is_absolute()
                || p.components()
                    .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
            {
                return Err(format!(
                    "load_bitmap(\"{rel}\"): only paths inside the script's folder are allowed"
                )
                .into());
            }
            Bitmap::load(&dir.join(p)).map_err(err)
        });
        e.register_get("width", |b: &mut Bitmap| b.width() as i64);
        e.register_get("height", |b: &mut Bitmap| b.height() as i64);
        e.register_fn("ink", |b: &mut Bitmap, x: i64, y: i64| {
            x >= 0 && y >= 0 && b.ink(x as u32, y as u32)
        });
        e
    }
}

fn describe(e: &EvalAltResult) -> String {
    match e {
        EvalAltResult::ErrorInFunctionCall(name, _, inner, _) => {
            format!("in `{name}`: {}", describe(inner))
        }
        EvalAltResult::ErrorRuntime(d, _) => d.to_string(),
        other => {
            // Rhai appends " (line l, position p)" itself; keep the plain message.
            let s = other.to_string();
            match s.rfind(" (line ") {
                Some(i) => s[..i].to_string(),
                None => s,
            }
        }
    }
}

/// The signature of a function that was not found, innermost first.
fn not_found(e: &EvalAltResult) -> Option<&str> {
    match e {
        EvalAltResult::ErrorFunctionNotFound(sig, _) => Some(sig),
        EvalAltResult::ErrorInFunctionCall(_, _, inner, _) => not_found(inner),
        _ => None,
    }
}

/// Where the script's last expression is: its last line that holds code.
fn last_line(src: &str) -> Position {
    let line = src
        .lines()
        .enumerate()
        .filter(|(_, l)| {
            let t = l.trim();
            !t.is_empty() && !t.starts_with("//")
        })
        .map(|(i, _)| i + 1)
        .last()
        .unwrap_or(1);
    Position::new(line.min(u16::MAX as usize) as u16, 1)
}

/// How an error names a script function: closures have generated names (`anon$…`) that
/// mean nothing to the designer.
fn fn_label(f: &FnPtr) -> &str {
    if f.fn_name().starts_with("anon$") {
        "the closure"
    } else {
        f.fn_name()
    }
}

fn innermost_position(e: &EvalAltResult) -> Position {
    if let EvalAltResult::ErrorInFunctionCall(_, _, inner, pos) = e {
        let p = innermost_position(inner);
        if !p.is_none() {
            return p;
        }
        return *pos;
    }
    e.position()
}

fn register_turtle(e: &mut Engine) {
    e.register_type_with_name::<Turtle>("Turtle");
    e.register_fn(
        "init",
        |fd: Dynamic,
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
            .map_err(err)
        },
    );
    e.register_fn(
        "turtle",
        |x: Dynamic, y: Dynamic, z: Dynamic| -> Res<Turtle> {
            Ok(Turtle::at(
                DVec3::new(num(&x, "x")?, num(&y, "y")?, num(&z, "z")?),
                0.2,
                20.0,
            ))
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

fn register_model(e: &mut Engine, shared: Arc<Mutex<Shared>>) {
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

pub(super) fn arr3(p: DVec3) -> Dynamic {
    Dynamic::from_array(vec![
        Dynamic::from_float(p.x),
        Dynamic::from_float(p.y),
        Dynamic::from_float(p.z),
    ])
}

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
fn register_model_ops(e: &mut Engine, shared: Arc<Mutex<Shared>>, profile: Profile) {
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

fn register_parts(e: &mut Engine) {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn run(src: &str) -> Result<ScriptOutput, ScriptError> {
        ScriptRunner::new(Profile::ender3()).run("t.rhai", src, Path::new("."))
    }

    #[test]
    fn turtle_script_runs() {
        let out = run("let t = init(1.75, 200, 0, 0.2, 100, 100, 0.2);\n\
             let dz = 0.4 / 72;\n\
             for j in 0..2 { for i in 0..72 { t.forward(1, dz); t.left(5); } }\n\
             t")
        .expect("script");
        assert_eq!(out.model.string_count(), 144);
    }

    #[test]
    fn errors_point_at_the_line() {
        let e = run("let t = turtle(0, 0, 0);\n\nt.set_velocity(-1);\nt").err();
        let e = e.expect("must fail");
        assert_eq!(e.line, 3, "{e}");
        let e = run("let x = ;").expect_err("syntax");
        assert_eq!(e.line, 1);
        let e = run("helix(#{ radus: 3 })").expect_err("unknown option");
        assert!(e.msg.contains("radus"), "{e}");
        let e = run("42").expect_err("not a model");
        assert!(e.msg.contains("Model"));
    }

    #[test]
    fn operation_limit_stops_runaway_scripts() {
        let r = ScriptRunner::new(Profile::ender3())
            .with_limits(Limits {
                max_operations: 10_000,
                ..Limits::default()
            })
            .run(
                "t.rhai",
                "let t = turtle(0,0,0); loop { t.left(1); }",
                Path::new("."),
            );
        assert!(r.is_err());
    }

    #[test]
    fn deform_with_closures() {
        let out = run(
            "let h = helix(#{ cx: 0, cy: 0, radius: 10, turns: 1, per_turn: 8, z0: 0 });\n\
             h.deform_cylinder(|r, t, z| [r * 2.0, t, z], |c, r, t, z| c, |v, r, t, z| v * 2.0)",
        )
        .expect("deform");
        let s = out.model.strings().next().copied().expect("string");
        assert!((s.start.truncate().length() - 20.0).abs() < 1e-9);
        assert!((s.speed_mm_s - 40.0).abs() < 1e-9);
    }

    #[test]
    fn partition_split_and_reorder() {
        // Two helices as one design, taken apart by a predicate and reassembled B first.
        let out = run(
            "let a = helix(#{ cx: 50, cy: 50, radius: 5, turns: 2, per_turn: 10, z0: 0.2 });\n\
             let b = helix(#{ cx: 150, cy: 50, radius: 5, turns: 3, per_turn: 10, z0: 0.2 });\n\
             let h = (a + b).partition(|s| s.kind == \"string\" && s.end[0] < 100);\n\
             let t = h[1].split_at_markers(\"turn\");\n\
             if t.len() != 3 { throw `turns: ${t.len()}`; }\n\
             reorder_parts([h[0], t[0], t[1], t[2]], [3, 2, 1, 0])",
        )
        .expect("script");
        let xs: Vec<f64> = out.model.strings().map(|s| s.end.x).collect();
        assert_eq!(xs.len(), 50);
        // B's last turn first (z highest), then its other turns, then all of A.
        assert!(xs[..30].iter().all(|x| *x > 100.0));
        assert!(xs[30..].iter().all(|x| *x < 100.0));
        let z0 = out.model.strings().next().map(|s| s.start.z);
        assert!(z0.is_some_and(|z| (z - 1.0).abs() < 1e-9), "{z0:?}");
    }

    #[test]
    fn model_operation_errors_point_at_the_line() {
        let e = run("let h = helix(#{});\nh.partition(|s| 1)").expect_err("not a bool");
        assert_eq!(e.line, 2, "{e}");
        assert!(e.msg.contains("true or false"), "{e}");
        let e = run("let h = helix(#{});\n\nreorder_parts([h], [1])").expect_err("range");
        assert_eq!(e.line, 3, "{e}");
        assert!(e.msg.contains("out of range"), "{e}");
        let e = run("reorder_parts([helix(#{}), 3], [0, 1])").expect_err("not a model");
        assert!(e.msg.contains("not a Model"), "{e}");
        let e = run("helix(#{}).split_at_markers(\"ring\")").expect_err("kind");
        assert!(e.msg.contains("turn"), "{e}");
        let e = run("helix(#{}).map_strings(|i, c, v| [c, -v])").expect_err("bad speed");
        assert!(e.msg.contains("invalid"), "{e}");
    }

    #[test]
    fn assembly_modulation_subdivision_and_checks() {
        let out = run(
            "let parts = [helix(#{ turns: 1, per_turn: 20 }), helix(#{ turns: 1, per_turn: 20, z0: 0.6 })];\n\
             let m = assemble(parts);\n\
             let m = m.map_strings(|i, c, v| [c, if i < 10 { v * 2 } else { v }]);\n\
             let m = m.modulate_by(world_map(), 1.25, |i| if i % 2 == 0 { [150, 149] } else { () });\n\
             let b = m.bbox();\n\
             if b.max[2] < 0.6 { throw \"bbox\"; }\n\
             let r = m.check();\n\
             if r.total != r.issues.len() { throw \"issues\"; }\n\
             m",
        )
        .expect("script");
        let s: Vec<_> = out.model.strings().collect();
        assert_eq!(s.len(), 40);
        // map_strings doubled the first ten speeds; modulate_by slowed even strings (Antarctica
        // is ink) by 1.25 and widened them.
        assert!((s[0].speed_mm_s - 40.0 / 1.25).abs() < 1e-9, "{:?}", s[0]);
        assert!((s[1].speed_mm_s - 40.0).abs() < 1e-9);
        assert!((s[12].speed_mm_s - 20.0 / 1.25).abs() < 1e-9);
        assert!((s[12].cross_mm2 - 0.2 * 1.25).abs() < 1e-9);
        assert!((s[13].speed_mm_s - 20.0).abs() < 1e-9);
        // Subdivision: the sphere with a chord tolerance has more strings than without.
        let plain =
            run("helix(#{ turns: 4, per_turn: 8 }).helix_to_sphere(10, 1.6, 0.2)").expect("sphere");
        let fine = run("helix(#{ turns: 4, per_turn: 8 }).helix_to_sphere(10, 1.6, 0.2, 0.05)")
            .expect("sphere");
        assert!(fine.model.string_count() > plain.model.string_count());
    }

    #[test]
    fn sandbox_refuses_paths_outside() {
        let e = run("load_bitmap(\"../x.png\")").expect_err("refused");
        assert!(e.msg.contains("inside"), "{e}");
        let e = run("load_bitmap(\"/etc/passwd\")").expect_err("refused");
        assert!(e.msg.contains("inside"), "{e}");
    }
}
