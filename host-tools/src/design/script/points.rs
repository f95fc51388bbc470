//! Script functions for building from points (FullControl's reach): points, polar
//! coordinates, and the shapes and paths made of them (arcs, circles, polygons, spirals, waves,
//! moves and reflections of paths). A point is an array `[x, y, z]`; a path is an array of
//! points, so Rhai's own array functions (`+`, `reverse`, `map`, `extract`...) work on paths.

use super::args::{arr3, count, err, num, vec3_named, vec3_of, Opts, Res};
use crate::design::points::{self, PointsError};
use crate::design::transform::{self, Transform};
use glam::DVec3;
use rhai::{Array, Dynamic, Engine, Map};

pub(super) fn pt(d: &Dynamic, what: &str) -> Res<DVec3> {
    vec3_of(d, what)
}

pub(super) fn path_of(a: &Array, what: &str) -> Res<Vec<DVec3>> {
    a.iter()
        .enumerate()
        .map(|(i, d)| vec3_named(d, || format!("{what}: point {i}")))
        .collect()
}

fn array_of(ps: Result<Vec<DVec3>, PointsError>) -> Res<Array> {
    Ok(ps.map_err(err)?.into_iter().map(arr3).collect())
}

pub(super) fn flag(d: &Dynamic, what: &str) -> Res<bool> {
    d.as_bool()
        .map_err(|t| format!("{what}: expected true/false, got {t}").into())
}

/// A path of a point, three numbers and a count (`arc_xy`, `triangle_wave_xy`).
type Path5 = fn(DVec3, f64, f64, f64, usize) -> Result<Vec<DVec3>, PointsError>;

/// Registers `name(point, a, b, c, n)` calling `f`; `labels` name the five arguments in errors.
fn register_path5(e: &mut Engine, name: &str, labels: [&'static str; 5], f: Path5) {
    e.register_fn(
        name,
        move |p: Dynamic, a: Dynamic, b: Dynamic, c: Dynamic, n: Dynamic| -> Res<Array> {
            array_of(f(
                pt(&p, labels[0])?,
                num(&a, labels[1])?,
                num(&b, labels[2])?,
                num(&c, labels[3])?,
                count(&n, labels[4])?,
            ))
        },
    );
}

pub(super) fn register_points(e: &mut Engine) {
    e.register_fn(
        "point",
        |x: Dynamic, y: Dynamic, z: Dynamic| -> Res<Dynamic> {
            Ok(arr3(DVec3::new(
                num(&x, "x")?,
                num(&y, "y")?,
                num(&z, "z")?,
            )))
        },
    );
    for name in ["polar", "polar_to_point"] {
        e.register_fn(name, |c: Dynamic, r: Dynamic, a: Dynamic| -> Res<Dynamic> {
            Ok(arr3(points::polar(
                pt(&c, "centre")?,
                num(&r, "radius")?,
                num(&a, "angle")?,
            )))
        });
    }
    e.register_fn("point_to_polar", |p: Dynamic, o: Dynamic| -> Res<Map> {
        let (r, a) = points::to_polar(pt(&p, "point")?, pt(&o, "origin")?);
        let mut m = Map::new();
        m.insert("radius".into(), Dynamic::from_float(r));
        m.insert("angle".into(), Dynamic::from_float(a));
        Ok(m)
    });
    e.register_fn("distance", |a: Dynamic, b: Dynamic| -> Res<f64> {
        Ok(pt(&a, "a")?.distance(pt(&b, "b")?))
    });
    e.register_fn("midpoint", |a: Dynamic, b: Dynamic| -> Res<Dynamic> {
        Ok(arr3(pt(&a, "a")?.lerp(pt(&b, "b")?, 0.5)))
    });
    e.register_fn("path_length", |a: Array| -> Res<f64> {
        Ok(points::path_length(&path_of(&a, "path_length")?))
    });
    register_path5(
        e,
        "arc_xy",
        ["centre", "radius", "start angle", "sweep", "segments"],
        points::arc_xy,
    );
    e.register_fn(
        "variable_arc_xy",
        |c: Dynamic,
         r: Dynamic,
         a0: Dynamic,
         sweep: Dynamic,
         n: Dynamic,
         dr: Dynamic,
         dz: Dynamic|
         -> Res<Array> {
            array_of(points::variable_arc_xy(
                pt(&c, "centre")?,
                num(&r, "radius")?,
                num(&a0, "start angle")?,
                num(&sweep, "sweep")?,
                count(&n, "segments")?,
                num(&dr, "radius change")?,
                num(&dz, "z change")?,
            ))
        },
    );
    // Closed shapes, counter-clockwise by default, with an optional trailing `cw` flag.
    type Shape = fn(&Dynamic, &Dynamic, &Dynamic, &Dynamic, bool) -> Res<Array>;
    let shapes: [(&str, Shape); 3] = [
        ("circle_xy", |c, r, a0, n, cw| {
            array_of(points::circle_xy(
                pt(c, "centre")?,
                num(r, "radius")?,
                num(a0, "start angle")?,
                count(n, "segments")?,
                cw,
            ))
        }),
        ("polygon_xy", |c, r, a0, n, cw| {
            array_of(points::polygon_xy(
                pt(c, "centre")?,
                num(r, "radius")?,
                num(a0, "start angle")?,
                count(n, "sides")?,
                cw,
            ))
        }),
        ("rectangle_xy", |s, x, y, _unused, cw| {
            array_of(points::rectangle_xy(
                pt(s, "start")?,
                num(x, "x size")?,
                num(y, "y size")?,
                cw,
            ))
        }),
    ];
    for (name, f) in shapes {
        if name == "rectangle_xy" {
            e.register_fn(name, move |s: Dynamic, x: Dynamic, y: Dynamic| {
                f(&s, &x, &y, &Dynamic::UNIT, false)
            });
            e.register_fn(
                name,
                move |s: Dynamic, x: Dynamic, y: Dynamic, cw: Dynamic| -> Res<Array> {
                    f(&s, &x, &y, &Dynamic::UNIT, flag(&cw, "cw")?)
                },
            );
        } else {
            e.register_fn(
                name,
                move |c: Dynamic, r: Dynamic, a0: Dynamic, n: Dynamic| f(&c, &r, &a0, &n, false),
            );
            e.register_fn(
                name,
                move |c: Dynamic, r: Dynamic, a0: Dynamic, n: Dynamic, cw: Dynamic| -> Res<Array> {
                    f(&c, &r, &a0, &n, flag(&cw, "cw")?)
                },
            );
        }
    }
    let spiral = |c: &Dynamic,
                  r0: &Dynamic,
                  r1: &Dynamic,
                  a0: &Dynamic,
                  t: &Dynamic,
                  n: &Dynamic,
                  cw: bool| {
        array_of(points::spiral_xy(
            pt(c, "centre")?,
            num(r0, "start radius")?,
            num(r1, "end radius")?,
            num(a0, "start angle")?,
            num(t, "turns")?,
            count(n, "segments")?,
            cw,
        ))
    };
    e.register_fn(
        "spiral_xy",
        move |c: Dynamic, r0: Dynamic, r1: Dynamic, a0: Dynamic, t: Dynamic, n: Dynamic| {
            spiral(&c, &r0, &r1, &a0, &t, &n, false)
        },
    );
    e.register_fn(
        "spiral_xy",
        move |c: Dynamic,
              r0: Dynamic,
              r1: Dynamic,
              a0: Dynamic,
              t: Dynamic,
              n: Dynamic,
              cw: Dynamic|
              -> Res<Array> { spiral(&c, &r0, &r1, &a0, &t, &n, flag(&cw, "cw")?) },
    );
    let helix = |a: [&Dynamic; 7], cw: bool| {
        array_of(points::helix_z(
            pt(a[0], "centre")?,
            num(a[1], "start radius")?,
            num(a[2], "end radius")?,
            num(a[3], "start angle")?,
            num(a[4], "turns")?,
            num(a[5], "pitch")?,
            count(a[6], "segments")?,
            cw,
        ))
    };
    e.register_fn(
        "helix_z",
        move |c: Dynamic,
              r0: Dynamic,
              r1: Dynamic,
              a0: Dynamic,
              t: Dynamic,
              pitch: Dynamic,
              n: Dynamic| { helix([&c, &r0, &r1, &a0, &t, &pitch, &n], false) },
    );
    e.register_fn(
        "helix_z",
        move |c: Dynamic,
              r0: Dynamic,
              r1: Dynamic,
              a0: Dynamic,
              t: Dynamic,
              pitch: Dynamic,
              n: Dynamic,
              cw: Dynamic|
              -> Res<Array> {
            helix([&c, &r0, &r1, &a0, &t, &pitch, &n], flag(&cw, "cw")?)
        },
    );
    let sine = |s: &Dynamic, a: &Dynamic, amp: &Dynamic, per: &Dynamic, n: &Dynamic, o: &Map| {
        let o = Opts::new(
            o,
            "sine_wave_xy",
            &["segments_per_period", "extra_half_period", "phase"],
        )?;
        array_of(points::sine_wave_xy(
            pt(s, "start")?,
            num(a, "direction angle")?,
            num(amp, "amplitude")?,
            num(per, "period")?,
            count(n, "periods")?,
            o.n("segments_per_period", 16)?,
            o.b("extra_half_period", false)?,
            o.f("phase", 0.0)?,
        ))
    };
    e.register_fn(
        "sine_wave_xy",
        move |s: Dynamic, a: Dynamic, amp: Dynamic, per: Dynamic, n: Dynamic| {
            sine(&s, &a, &amp, &per, &n, &Map::new())
        },
    );
    e.register_fn(
        "sine_wave_xy",
        move |s: Dynamic, a: Dynamic, amp: Dynamic, per: Dynamic, n: Dynamic, o: Map| {
            sine(&s, &a, &amp, &per, &n, &o)
        },
    );
    let square = |s: &Dynamic, a: &Dynamic, amp: &Dynamic, sp: &Dynamic, n: &Dynamic, x: bool| {
        array_of(points::square_wave_xy(
            pt(s, "start")?,
            num(a, "direction angle")?,
            num(amp, "amplitude")?,
            num(sp, "line spacing")?,
            count(n, "periods")?,
            x,
        ))
    };
    e.register_fn(
        "square_wave_xy",
        move |s: Dynamic, a: Dynamic, amp: Dynamic, sp: Dynamic, n: Dynamic| {
            square(&s, &a, &amp, &sp, &n, false)
        },
    );
    e.register_fn(
        "square_wave_xy",
        move |s: Dynamic,
              a: Dynamic,
              amp: Dynamic,
              sp: Dynamic,
              n: Dynamic,
              x: Dynamic|
              -> Res<Array> {
            square(&s, &a, &amp, &sp, &n, flag(&x, "extra_half_period")?)
        },
    );
    register_path5(
        e,
        "triangle_wave_xy",
        [
            "start",
            "direction angle",
            "amplitude",
            "tip spacing",
            "periods",
        ],
        points::triangle_wave_xy,
    );
    e.register_fn(
        "segmented_line",
        |a: Dynamic, b: Dynamic, n: Dynamic| -> Res<Array> {
            array_of(points::segmented_line(
                pt(&a, "start")?,
                pt(&b, "end")?,
                count(&n, "segments")?,
            ))
        },
    );
    e.register_fn("subdivide", |a: Array, max_len: Dynamic| -> Res<Array> {
        let p = path_of(&a, "subdivide")?;
        array_of(points::subdivide(&p, num(&max_len, "max length")?))
    });
    e.register_fn("move_points", |a: Array, v: Dynamic| -> Res<Array> {
        let p = path_of(&a, "move_points")?;
        Ok(points::moved(&p, pt(&v, "vector")?)
            .into_iter()
            .map(arr3)
            .collect())
    });
    e.register_fn(
        "copy_points",
        |a: Array, v: Dynamic, n: Dynamic| -> Res<Array> {
            let p = path_of(&a, "copy_points")?;
            array_of(points::copied(&p, pt(&v, "vector")?, count(&n, "copies")?))
        },
    );
    register_transforms(e);
    e.register_fn(
        "reflect_xy",
        |a: Array, p1: Dynamic, p2: Dynamic| -> Res<Array> {
            let (p1, p2) = (pt(&p1, "mirror point 1")?, pt(&p2, "mirror point 2")?);
            // One point ([x, y, z]) or a path of points.
            if is_point(&a) {
                let p = pt(&Dynamic::from_array(a), "point")?;
                return Ok(xyz(points::reflect_xy(p, p1, p2).map_err(err)?));
            }
            let p = path_of(&a, "reflect_xy")?;
            array_of(
                p.into_iter()
                    .map(|p| points::reflect_xy(p, p1, p2))
                    .collect(),
            )
        },
    );
}

/// A point as the array `[x, y, z]` (not wrapped in a `Dynamic`, as [`arr3`] does).
fn xyz(p: DVec3) -> Array {
    vec![
        Dynamic::from_float(p.x),
        Dynamic::from_float(p.y),
        Dynamic::from_float(p.z),
    ]
}

/// True when the array is one point (`[x, y, z]` of numbers), not a path.
fn is_point(a: &Array) -> bool {
    a.len() == 3 && a.iter().all(|d| d.as_float().is_ok() || d.as_int().is_ok())
}

/// A point or a path transformed (a point stays a point).
fn transformed(a: Array, t: &Transform, what: &str) -> Res<Array> {
    if is_point(&a) {
        let p = pt(&Dynamic::from_array(a), what)?;
        t.validate().map_err(err)?;
        return Ok(xyz(t.apply(p)));
    }
    let p = path_of(&a, what)?;
    Ok(transform::path(&p, t)
        .map_err(err)?
        .into_iter()
        .map(arr3)
        .collect())
}

/// A scale factor: one number (uniform) or `[kx, ky, kz]`.
fn factor(d: &Dynamic) -> Res<DVec3> {
    if d.is_array() {
        vec3_of(d, "scale factors")
    } else {
        Ok(DVec3::splat(num(d, "scale factor")?))
    }
}

/// The transform of `rotate_xy(.., centre, angle)` (on points, paths and models).
pub(super) fn rotation(c: &Dynamic, angle: &Dynamic) -> Res<Transform> {
    Ok(Transform::RotateXy {
        centre: pt(c, "centre")?.truncate(),
        angle: num(angle, "angle")?,
    })
}

/// The transform of `scale(.., centre, k)` (on points, paths and models).
pub(super) fn scaling(c: &Dynamic, k: &Dynamic) -> Res<Transform> {
    Ok(Transform::Scale {
        centre: pt(c, "centre")?,
        k: factor(k)?,
    })
}

/// The transform of `move_polar(.., centre, radius, angle[, copies])` (on points, paths and
/// models).
pub(super) fn polar(c: &Dynamic, r: &Dynamic, angle: &Dynamic) -> Res<Transform> {
    Ok(Transform::Polar {
        centre: pt(c, "centre")?.truncate(),
        radius: num(r, "radius")?,
        angle: num(angle, "angle")?,
    })
}

/// `rotate_xy`, `scale` and `move_polar` on points and paths.
fn register_transforms(e: &mut Engine) {
    e.register_fn(
        "rotate_xy",
        |a: Array, c: Dynamic, angle: Dynamic| -> Res<Array> {
            transformed(a, &rotation(&c, &angle)?, "rotate_xy")
        },
    );
    e.register_fn("scale", |a: Array, c: Dynamic, k: Dynamic| -> Res<Array> {
        transformed(a, &scaling(&c, &k)?, "scale")
    });
    e.register_fn(
        "move_polar",
        |a: Array, c: Dynamic, r: Dynamic, angle: Dynamic| -> Res<Array> {
            transformed(a, &polar(&c, &r, &angle)?, "move_polar")
        },
    );
    e.register_fn(
        "move_polar",
        |a: Array, c: Dynamic, r: Dynamic, angle: Dynamic, n: Dynamic| -> Res<Array> {
            let p = if is_point(&a) {
                vec![pt(&Dynamic::from_array(a), "move_polar")?]
            } else {
                path_of(&a, "move_polar")?
            };
            let out = transform::copies(
                &p,
                &polar(&c, &r, &angle)?,
                count(&n, "copies")?,
                points::MAX_POINTS,
            )
            .map_err(err)?;
            Ok(out.into_iter().map(arr3).collect())
        },
    );
}
