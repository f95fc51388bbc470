//! Design scripts in Rhai: a sandboxed, embedded language calling the same API as Rust code.
//!
//! The sandbox: no file or network access except reading PNG bitmaps next to the script
//! (`load_bitmap("map.png")`, no absolute paths, no `..`), no modules, and limits on
//! operations, call depth, string, array and map sizes. A script's last expression is the
//! design: a `Model` or a `Turtle` (its drawing). Errors carry the script line and column.
//!
//! See `docs/design.md` for the full list of functions; `host-tools/examples/*.rhai` use all
//! of them.
//!
//! This module runs scripts (the sandboxed engine, the bed constants, errors with their place);
//! the functions scripts call are registered by family in its submodules: `turtle`, `model`,
//! `model_ops`, `parts`, `points` (FullControl-style building from points), `pen` (pen moves and
//! state changes at any point) and `aliases` (other tools' names, hints for unknown ones);
//! `args` reads their arguments.

mod aliases;
mod args;
mod guards;
mod model;
mod model_ops;
mod parts;
mod pen;
mod points;
mod turtle;

use args::{err, Res};

use crate::design::model::Model;
use crate::design::modulate::Bitmap;
use crate::design::profile::Profile;
use crate::design::turtle::Turtle;
use rhai::packages::{Package, StandardPackage};
use rhai::{Dynamic, Engine, EvalAltResult, FnPtr, Position, Scope};
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Limits of the sandbox.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Most operations one script may run.
    pub max_operations: u64,
    /// Deepest function call nesting.
    pub max_call_levels: usize,
    /// Most heap the script may add while it runs, bytes (checked between operations
    /// through [`crate::mem`]; Rhai's per-value size limits made every append to a path
    /// O(path length), see there).
    pub max_memory_bytes: usize,
    /// Most elements (or bytes) one `pad` or `blob` call may make: the one way a single
    /// operation allocates by a number the script gives.
    pub max_pad: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_operations: 200_000_000,
            max_call_levels: 64,
            max_memory_bytes: 1 << 30,
            max_pad: 10_000_000,
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
            if let Some(h) = not_found(&e).and_then(|sig| aliases::hint(&engine, sig)) {
                msg = format!("{msg} ({h})");
            }
            // Whatever Rhai put in its message (a closure's signature in "function not
            // found", a call stack), never its generated closure names.
            at(without_closure_names(&msg), innermost_position(&e))
        })?;
        // The script's variables hold what the result may share (a final `t` is a copy of
        // the turtle, sharing its model): dropped first, the model is taken without a copy.
        drop(scope);
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
        // No per-value size limits (0 = none): Rhai re-measures a whole value after every
        // call that may change it, which made appending to a path quadratic. The heap as a
        // whole is bounded instead (below), and the calls that allocate by a number are
        // bounded by `guards`.
        e.set_max_string_size(0);
        e.set_max_array_size(0);
        e.set_max_map_size(0);
        e.set_max_expr_depths(128, 64);
        e.on_print(|s| eprintln!("{s}"));
        e.on_debug(|s, _, pos| eprintln!("debug {pos}: {s}"));
        let progress = self.progress.clone();
        let budget = crate::mem::in_use().saturating_add(self.limits.max_memory_bytes);
        e.on_progress(move |ops| {
            if ops % 1_000_000 == 0 {
                if let Some(p) = &progress {
                    p(ops);
                }
            }
            (crate::mem::in_use() > budget).then(|| Dynamic::from(MEMORY_TOKEN))
        });
        guards::register_guards(&mut e, self.limits.max_pad);
        {
            let sh = shared.clone();
            e.register_fn("warn", move |msg: &str| {
                if let Ok(mut s) = sh.lock() {
                    s.warnings.push(msg.to_string());
                }
            });
        }
        turtle::register_turtle(&mut e, self.profile.clone());
        model::register_model(&mut e, shared.clone());
        model_ops::register_model_ops(&mut e, shared, self.profile.clone());
        parts::register_parts(&mut e);
        points::register_points(&mut e);
        pen::register_pen(&mut e, std::rc::Rc::new(self.profile.clone()));
        model::register_model_geometry(&mut e);
        aliases::register_kanada(&mut e);
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

/// What the progress callback stops a script with when it exceeds its memory budget.
const MEMORY_TOKEN: &str = "memory budget";

fn describe(e: &EvalAltResult) -> String {
    match e {
        EvalAltResult::ErrorTerminated(token, _)
            if token.clone().into_string().is_ok_and(|t| t == MEMORY_TOKEN) =>
        {
            "the script uses more memory than the sandbox allows (`compile --max-memory-mib`, 1 GiB by default)".to_string()
        }
        EvalAltResult::ErrorInFunctionCall(name, _, inner, _) => {
            if is_closure_name(name) {
                format!("in the closure: {}", describe(inner))
            } else {
                format!("in `{name}`: {}", describe(inner))
            }
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

/// True for the generated name of a closure (`anon$…`).
fn is_closure_name(name: &str) -> bool {
    name.starts_with("anon$")
}

/// How an error names a script function: closures have generated names (`anon$…`) that
/// mean nothing to the designer.
fn fn_label(f: &FnPtr) -> &str {
    if is_closure_name(f.fn_name()) {
        "the closure"
    } else {
        f.fn_name()
    }
}

/// Replaces every generated closure name (`anon$` and its hex digits) in a message.
fn without_closure_names(msg: &str) -> String {
    let mut out = String::with_capacity(msg.len());
    let mut rest = msg;
    while let Some(i) = rest.find("anon$") {
        out.push_str(&rest[..i]);
        let tail = &rest[i + 5..];
        let end = tail
            .find(|c: char| !c.is_ascii_alphanumeric() && c != '_')
            .unwrap_or(tail.len());
        out.push_str("the closure");
        rest = &tail[end..];
    }
    out.push_str(rest);
    out
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

    /// Issue 23's hints: each names a function that does the job; none shows `anon$`.
    #[test]
    fn hints_name_the_right_function_and_never_a_closure_name() {
        for (src, want) in [
            ("let t = turtle(0, 0, 0.2); t.set_fan(50); t", "`fan"),
            ("arc(point(0, 0, 0), 5, 0, 1, 8)", "arc_xy"),
            ("let t = turtle(0, 0, 0.2); t.rotate(90); t", "left"),
            ("rotate([point(1, 0, 0)], point(0, 0, 0), 1)", "rotate_xy"),
            (
                "let t = turtle(0, 0, 0.2); t.extrude_too(point(1, 0, 0.2)); t",
                "extrude_to",
            ),
        ] {
            let e = run(src).expect_err(src);
            assert!(e.msg.contains(want), "{src}: {e}");
        }
        assert!(run(
            "let t = turtle(0, 0, 0.2); t.set_travel_speed(100); t.extrude_to(point(5, 0, 0.2)); t"
        )
        .is_ok());
        for src in [
            "let a = [1, 2].map(|x| x.nope()); turtle(0, 0, 0)",
            "let f = |x| x + y; f.call(1)",
            "let h = helix(#{}); h.partition(|s| s.nope)",
        ] {
            let e = run(src).expect_err(src);
            assert!(
                !e.msg.contains("anon$") && !e.to_string().contains("anon$"),
                "{src}: {e}"
            );
        }
    }

    /// `move_polar` rotates (the hint it used to get, `polar + move_points`, could not), for
    /// points, paths and models, with copies.
    #[test]
    fn move_polar_rotate_and_scale_from_scripts() {
        let out = run(
            "let p = move_polar([point(15, 10, 0.2), point(20, 10, 0.2)], point(10, 10, 0), 0, PI / 2);\n\
             if (p[0][0] - 10.0).abs() > 1e-9 || (p[0][1] - 15.0).abs() > 1e-9 { throw `${p}`; }\n\
             let q = move_polar(point(15, 10, 0), point(10, 10, 0), 1, PI);\n\
             if (q[0] - 4.0).abs() > 1e-9 { throw `${q}`; }\n\
             let r = rotate_xy(point(1, 0, 0), point(0, 0, 0), PI / 2);\n\
             if r[1] < 0.999 { throw `${r}`; }\n\
             let s = scale([point(2, 2, 2)], point(1, 1, 1), [2, 3, 1]);\n\
             if s[0][0] != 3.0 || s[0][1] != 4.0 || s[0][2] != 2.0 { throw `${s}`; }\n\
             let ring = move_polar([point(60, 50, 0.2)], point(50, 50, 0), 0, PI / 2, 4);\n\
             if ring.len() != 4 || (ring[3][1] - 40.0).abs() > 1e-9 { throw `${ring}`; }\n\
             let h = helix(#{ cx: 60, cy: 50, radius: 2, turns: 1, per_turn: 8 });\n\
             h.move_polar(point(50, 50, 0), 0, PI / 2, 4)",
        )
        .expect("script");
        // Four copies of the 8-string turn, a quarter turn apart about (50, 50).
        assert_eq!(out.model.string_count(), 32);
        let ends: Vec<_> = out.model.strings().map(|s| s.end).collect();
        assert!(ends.iter().any(|p| (p.x - 50.0).abs() < 2.01 && p.y > 57.9));
        assert!(ends.iter().any(|p| p.x < 42.1 && (p.y - 50.0).abs() < 2.01));
        let e = run("init(#{ relative_e: true })").expect_err("unknown key");
        assert!(
            e.msg.contains("relative_e") && e.msg.contains("nozzle_temp"),
            "{e}"
        );
        let e = run("init(#{ print_speed: 1000 })").expect_err("mm/min");
        assert!(e.msg.contains("mm/min"), "{e}");
    }

    #[test]
    fn sandbox_refuses_paths_outside() {
        let e = run("load_bitmap(\"../x.png\")").expect_err("refused");
        assert!(e.msg.contains("inside"), "{e}");
        let e = run("load_bitmap(\"/etc/passwd\")").expect_err("refused");
        assert!(e.msg.contains("inside"), "{e}");
    }
}
