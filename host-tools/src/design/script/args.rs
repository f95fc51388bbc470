//! Reading script arguments: numbers, counts, points and option maps with defaults (unknown
//! keys refused), and the error type every registered function returns.

use glam::DVec3;
use rhai::{Dynamic, EvalAltResult, Map};

pub(super) type Res<T> = Result<T, Box<EvalAltResult>>;

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
    vec3_named(d, || what.to_string())
}

/// [`vec3_of`] with the name made only for an error (a path of 45,000 points formatted a
/// name per point: 7 % of compiling FullControl's helix).
pub(super) fn vec3_named(d: &Dynamic, what: impl Fn() -> String) -> Res<DVec3> {
    // Read in place: a clone of the array was an allocation per point.
    let arr = d
        .as_array_ref()
        .map_err(|t| format!("{}: expected an array [a, b, c], got {t}", what()))?;
    if arr.len() != 3 {
        return Err(format!("{}: expected 3 numbers, got {}", what(), arr.len()).into());
    }
    let coord = |v: &Dynamic| -> Res<f64> {
        if let Ok(f) = v.as_float() {
            Ok(f)
        } else if let Ok(i) = v.as_int() {
            Ok(i as f64)
        } else {
            Err(format!("{}: expected a number, got {}", what(), v.type_name()).into())
        }
    };
    Ok(DVec3::new(
        coord(&arr[0])?,
        coord(&arr[1])?,
        coord(&arr[2])?,
    ))
}

pub(super) fn err<E: std::fmt::Display>(e: E) -> Box<EvalAltResult> {
    e.to_string().into()
}

pub(super) fn arr3(p: DVec3) -> Dynamic {
    Dynamic::from_array(vec![
        Dynamic::from_float(p.x),
        Dynamic::from_float(p.y),
        Dynamic::from_float(p.z),
    ])
}
