//! Math functions that return NaN for some arguments (`sqrt(-1)`, `ln(-2)`, `acos(2)`) are
//! replaced by the same functions raising an error at their call, so the error points at the
//! `sqrt` that made the NaN, not at the `extrude_to` far away that meets it.
//!
//! The built-in functions that allocate by a number the script gives — `pad` on arrays,
//! strings and blobs, `blob(len)` — replaced by the same functions with a bound, so one call
//! cannot ask for an unbounded allocation now that the sandbox bounds the heap as a whole
//! between operations instead of every value after every call (see `crate::mem`). Functions
//! registered on the engine are found before the standard package's of the same signature.

use super::args::Res;
use rhai::{Array, Blob, Dynamic, Engine, ImmutableString};

fn bounded(what: &str, len: i64, max: usize) -> Res<usize> {
    match usize::try_from(len) {
        Ok(n) if n <= max => Ok(n),
        Ok(_) => {
            Err(format!("{what}: {len} is more than the sandbox allows in one call ({max})").into())
        }
        Err(_) => Ok(0),
    }
}

/// `f(x)`, or an error naming the call when it is not a number.
fn math1(name: &'static str, f: fn(f64) -> f64, why: &'static str) -> impl Fn(f64) -> Res<f64> {
    move |x: f64| {
        let y = f(x);
        if y.is_nan() && !x.is_nan() {
            return Err(format!("{name}({x}) is not a number ({why})").into());
        }
        Ok(y)
    }
}

/// A guarded one-argument function: its script name, the function, why a NaN comes out.
type Math1 = (&'static str, fn(f64) -> f64, &'static str);

/// Registers the NaN-checked math functions for floats and integers.
fn register_math(e: &mut Engine) {
    let one: [Math1; 7] = [
        ("sqrt", f64::sqrt, "square root of a negative number"),
        ("ln", f64::ln, "logarithm of a negative number"),
        ("log", f64::log10, "logarithm of a negative number"),
        ("asin", f64::asin, "arc sine of a value beyond ±1"),
        ("acos", f64::acos, "arc cosine of a value beyond ±1"),
        ("acosh", f64::acosh, "area cosine of a value below 1"),
        ("atanh", f64::atanh, "area tangent of a value beyond ±1"),
    ];
    for (name, f, why) in one {
        let g = math1(name, f, why);
        e.register_fn(name, move |x: f64| g(x));
        let g = math1(name, f, why);
        e.register_fn(name, move |x: i64| g(x as f64));
    }
    e.register_fn("log", |x: f64, base: f64| -> Res<f64> {
        let y = x.log(base);
        if y.is_nan() && !(x.is_nan() || base.is_nan()) {
            return Err(format!("log({x}, {base}) is not a number").into());
        }
        Ok(y)
    });
}

pub(super) fn register_guards(e: &mut Engine, max: usize) {
    register_math(e);
    e.register_fn(
        "pad",
        move |a: &mut Array, len: i64, item: Dynamic| -> Res<()> {
            let n = bounded("pad", len, max)?;
            if n > a.len() {
                a.resize(n, item);
            }
            Ok(())
        },
    );
    e.register_fn(
        "pad",
        move |s: &mut ImmutableString, len: i64, c: char| -> Res<()> {
            let n = bounded("pad", len, max)?;
            let have = s.chars().count();
            if n > have {
                let mut t = s.to_string();
                t.extend(std::iter::repeat_n(c, n - have));
                *s = t.into();
            }
            Ok(())
        },
    );
    e.register_fn(
        "pad",
        move |s: &mut ImmutableString, len: i64, padding: &str| -> Res<()> {
            let n = bounded("pad", len, max)?;
            let have = s.chars().count();
            if n > have && !padding.is_empty() {
                let mut t = s.to_string();
                t.extend(padding.chars().cycle().take(n - have));
                *s = t.into();
            }
            Ok(())
        },
    );
    e.register_fn("blob", move |len: i64| -> Res<Blob> {
        Ok(vec![0; bounded("blob", len, max)?])
    });
    e.register_fn("blob", move |len: i64, v: i64| -> Res<Blob> {
        Ok(vec![(v & 0xff) as u8; bounded("blob", len, max)?])
    });
    e.register_fn("pad", move |b: &mut Blob, len: i64, v: i64| -> Res<()> {
        let n = bounded("pad", len, max)?;
        if n > b.len() {
            b.resize(n, (v & 0xff) as u8);
        }
        Ok(())
    });
}
