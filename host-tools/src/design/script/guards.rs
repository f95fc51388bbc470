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

pub(super) fn register_guards(e: &mut Engine, max: usize) {
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
