//! The field-oriented solid model (Kanada; FullControl style): a design is an ordered list of
//! [`Step`]s — extruded strings, travels, comments, layer/turn markers and state changes.
//!
//! A string `S_i = (P_start, P_end, c_i, v_i)` is a straight segment (or a true arc) extruded
//! with cross-section `c_i` (mm²) at head speed `v_i` (mm/s). Every modelling operation takes a
//! [`Model`] and returns a [`Model`]: assembly ([`Model::then`], [`Model::assemble`]),
//! partitioning ([`Model::partition`]) and reordering ([`Model::reorder_parts`]), deformation
//! (`deform`), modulation (`modulate`).
//!
//! A string whose start is not where the previous one ended is reached by an implicit travel
//! (pen up) when the model is written, so parts can be assembled without caring about joins.

use glam::DVec3;

/// Height above everything printed so far at which [`Model::assemble`] travels between
/// parts, mm.
pub const ASSEMBLY_CLEARANCE_MM: f64 = 1.0;

/// Largest number of strings one model operation may make (guards scripts against runaway
/// sizes: parts, subdivision, copies).
pub const MAX_STRINGS: usize = 20_000_000;

/// A true circular arc in the XY plane (optionally rising in Z: a helical arc), written as
/// G2/G3 when the design keeps it; deformations turn arcs into straight strings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arc {
    /// Arc centre (X, Y), mm.
    pub center_xy: [f64; 2],
    /// Counter-clockwise (G3) when true, clockwise (G2) when false.
    pub ccw: bool,
}

/// One extruded string.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Str {
    /// Start point, mm.
    pub start: DVec3,
    /// End point, mm.
    pub end: DVec3,
    /// Cross-section of the extruded string, mm² (stands for filament density).
    pub cross_mm2: f64,
    /// Head speed, mm/s.
    pub speed_mm_s: f64,
    /// Present when the string is a true arc from `start` to `end`.
    pub arc: Option<Arc>,
}

impl Str {
    /// A straight string.
    pub fn line(start: DVec3, end: DVec3, cross_mm2: f64, speed_mm_s: f64) -> Self {
        Str {
            start,
            end,
            cross_mm2,
            speed_mm_s,
            arc: None,
        }
    }

    /// Path length, mm (arc length for arcs, including the rise in Z).
    pub fn len_mm(&self) -> f64 {
        match self.arc {
            None => self.start.distance(self.end),
            Some(a) => {
                let sweep = arc_sweep_rad(self.start, self.end, a);
                let r = (self.start.truncate() - glam::DVec2::from(a.center_xy)).length();
                let planar = sweep.abs() * r;
                let dz = self.end.z - self.start.z;
                (planar * planar + dz * dz).sqrt()
            }
        }
    }

    /// Extruded volume, mm³.
    pub fn volume_mm3(&self) -> f64 {
        self.cross_mm2 * self.len_mm()
    }

    /// Volumetric flow while printing this string, mm³/s.
    pub fn flow_mm3_s(&self) -> f64 {
        self.cross_mm2 * self.speed_mm_s
    }
}

/// Adds the points where arc string `s` turns through the ±X and ±Y directions of its centre
/// (at the height it has there: the Z of a helical arc changes linearly with the angle).
fn add_arc_extremes(b: &mut BBox, s: &Str, a: Arc) {
    let c = glam::DVec2::from(a.center_xy);
    let r = (s.start.truncate() - c).length();
    let a0 = (s.start.y - c.y).atan2(s.start.x - c.x);
    let sweep = arc_sweep_rad(s.start, s.end, a);
    if !(r.is_finite() && sweep.is_finite()) || sweep == 0.0 {
        return;
    }
    for k in 0..4 {
        let axis = f64::from(k) * std::f64::consts::FRAC_PI_2;
        // The first turn of the sweep's direction at which the arc points along `axis`.
        let mut d = (axis - a0).rem_euclid(std::f64::consts::TAU);
        if sweep < 0.0 {
            d = (a0 - axis).rem_euclid(std::f64::consts::TAU);
        }
        if d <= sweep.abs() {
            let t = d / sweep.abs();
            let z = s.start.z + (s.end.z - s.start.z) * t;
            b.add(DVec3::new(c.x + r * axis.cos(), c.y + r * axis.sin(), z));
        }
    }
}

/// Signed sweep of an arc from `start` to `end` about its centre, radians: positive for
/// counter-clockwise; a full circle when start and end coincide.
pub fn arc_sweep_rad(start: DVec3, end: DVec3, arc: Arc) -> f64 {
    let c = glam::DVec2::from(arc.center_xy);
    let a0 = (start.truncate() - c).to_angle();
    let a1 = (end.truncate() - c).to_angle();
    let mut d = a1 - a0;
    if arc.ccw {
        while d <= 1e-12 {
            d += std::f64::consts::TAU;
        }
    } else {
        while d >= -1e-12 {
            d -= std::f64::consts::TAU;
        }
    }
    d
}

/// A change of machine state between moves.
#[derive(Clone, Debug, PartialEq)]
pub enum StateChange {
    /// Hotend target, °C; `wait` blocks until reached (M109) instead of M104.
    HotendTemp {
        /// Target, °C.
        celsius: f64,
        /// Wait until reached.
        wait: bool,
    },
    /// Bed target, °C; `wait` blocks until reached (M190) instead of M140.
    BedTemp {
        /// Target, °C.
        celsius: f64,
        /// Wait until reached.
        wait: bool,
    },
    /// Part-cooling fan, 0..=1 of full speed.
    Fan(f64),
    /// Filament diameter used for E from here on, mm (the turtle's `init` argument).
    FilamentDiameter(f64),
    /// Retraction used by the travels from here on (replaces the profile's).
    Retraction(crate::design::profile::Retraction),
    /// Raw G-code lines written as they are (checked for line breaks and non-ASCII when
    /// written).
    Gcode(String),
    /// A pause mark for the firmware: `M601` (stop at the next layer boundary) or, with
    /// `now`, `M601 S1` (stop here).
    Pause {
        /// Pause at once instead of at the layer boundary.
        now: bool,
    },
    /// Speed of the travels from here on that do not name their own, mm/s (replaces the
    /// profile's `travel_speed_mm_s`).
    TravelSpeed(f64),
    /// Whether the profile's primer (its purge line) is written in the start code; only
    /// before the design's first move.
    Primer(crate::design::profile::Primer),
    /// The beads' cross-section model from here on (`set_extrusion`'s `area_model`), written
    /// as the `;AREA_MODEL:` comment for the 3D page when it changes
    /// ([`crate::gcode::bead`]).
    Bead(crate::gcode::bead::AreaModel),
}

/// Kind of a progress marker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MarkerKind {
    /// A layer of a layered print.
    Layer,
    /// One turn of a layer-free (helical) print: written as a layer change so layer-based
    /// tools (viewers, the firmware's layer pause) stop at a turn boundary.
    Turn,
}

/// One step of a design.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    /// An extruded string.
    String(Str),
    /// A move without extrusion (pen up) to `to`; `speed_mm_s` `None` uses the profile's
    /// travel speed.
    Travel {
        /// Destination, mm.
        to: DVec3,
        /// Speed, mm/s, or the profile's travel speed.
        speed_mm_s: Option<f64>,
    },
    /// A comment copied into the G-code.
    Comment(String),
    /// Start of a layer or turn at height `z_mm` with thickness `height_mm`.
    Marker {
        /// Layer or turn.
        kind: MarkerKind,
        /// Height of the layer/turn, mm.
        z_mm: f64,
        /// Thickness (pitch for turns), mm.
        height_mm: f64,
    },
    /// Feature type for viewers (`;TYPE:`), e.g. "External perimeter".
    Type(String),
    /// A machine state change.
    State(StateChange),
}

/// Hints for the emission (drawing) step, not for the geometry: they travel with the model.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EmissionHints {
    /// Merge consecutive contiguous strings shorter than this (mm) when writing, keeping
    /// their volume and time (thinning near the poles of a globe). `None`: no thinning.
    pub thin_min_len_mm: Option<f64>,
}

/// A design: an ordered list of steps plus the part's axis (for cylindrical deformations).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Model {
    /// The steps, in print order.
    pub steps: Vec<Step>,
    /// Axis of cylindrical coordinates (X, Y), mm: the helix/turtle centre.
    pub axis_xy: [f64; 2],
    /// Emission hints.
    pub emission: EmissionHints,
}

/// Axis-aligned bounding box, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BBox {
    /// Lowest corner.
    pub min: DVec3,
    /// Highest corner.
    pub max: DVec3,
}

impl BBox {
    /// An empty box (min = +∞, max = −∞).
    pub fn empty() -> Self {
        BBox {
            min: DVec3::splat(f64::INFINITY),
            max: DVec3::splat(f64::NEG_INFINITY),
        }
    }
    /// Grows the box to contain `p`.
    pub fn add(&mut self, p: DVec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    /// True when nothing was added.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }
}

impl Model {
    /// An empty model with its axis at (x, y).
    pub fn new(axis_xy: [f64; 2]) -> Self {
        Model {
            steps: Vec::new(),
            axis_xy,
            emission: EmissionHints::default(),
        }
    }

    /// Appends a step (builder style).
    pub fn push(&mut self, step: Step) {
        self.steps.push(step);
    }

    /// Assembly: this model followed by `other` (the axis and hints of `self` are kept).
    pub fn then(mut self, other: Model) -> Model {
        self.steps.extend(other.steps);
        if self.emission.thin_min_len_mm.is_none() {
            self.emission = other.emission;
        }
        self
    }

    /// Assembly of many parts in order. Between parts that do not join, the head lifts
    /// straight up to [`ASSEMBLY_CLEARANCE_MM`] above everything printed so far (and above
    /// both ends), crosses at that height and descends onto the next part's first point: the
    /// travel never drives through a printed part.
    pub fn assemble(parts: impl IntoIterator<Item = Model>) -> Model {
        let mut it = parts.into_iter();
        let mut out = it.next().unwrap_or_default();
        let mut top_z = out.top_z();
        for part in it {
            if let (Some(from), Some(to), Some(top)) = (out.last_point(), part.first_point(), top_z)
            {
                if from != to {
                    let safe_z = top.max(from.z).max(to.z) + ASSEMBLY_CLEARANCE_MM;
                    for p in [
                        DVec3::new(from.x, from.y, safe_z),
                        DVec3::new(to.x, to.y, safe_z),
                        to,
                    ] {
                        out.push(Step::Travel {
                            to: p,
                            speed_mm_s: None,
                        });
                    }
                }
            }
            top_z = match (top_z, part.top_z()) {
                (Some(a), Some(b)) => Some(a.max(b)),
                (a, b) => a.or(b),
            };
            out = out.then(part);
        }
        out
    }

    /// Highest point of any string, mm; `None` without strings.
    fn top_z(&self) -> Option<f64> {
        self.strings()
            .map(|s| s.start.z.max(s.end.z))
            .reduce(f64::max)
    }

    /// Where the head is after the model: the end of its last string or travel.
    fn last_point(&self) -> Option<DVec3> {
        self.steps.iter().rev().find_map(|s| match s {
            Step::String(s) => Some(s.end),
            Step::Travel { to, .. } => Some(*to),
            _ => None,
        })
    }

    /// Where the model's first string or travel goes to first.
    fn first_point(&self) -> Option<DVec3> {
        self.steps.iter().find_map(|s| match s {
            Step::String(s) => Some(s.start),
            Step::Travel { to, .. } => Some(*to),
            _ => None,
        })
    }

    /// The strings, in order.
    pub fn strings(&self) -> impl Iterator<Item = &Str> {
        self.steps.iter().filter_map(|s| match s {
            Step::String(s) => Some(s),
            _ => None,
        })
    }

    /// Number of strings.
    pub fn string_count(&self) -> usize {
        self.strings().count()
    }

    /// Total extruded volume, mm³.
    pub fn volume_mm3(&self) -> f64 {
        self.strings().map(Str::volume_mm3).sum()
    }

    /// Bounding box of what is printed: every string, arcs with the points where they turn
    /// through ±X or ±Y — not travels (a lift 1 mm above the top is not the part's height).
    pub fn bbox(&self) -> BBox {
        let mut b = BBox::empty();
        for s in self.strings() {
            b.add(s.start);
            b.add(s.end);
            if let Some(a) = s.arc {
                add_arc_extremes(&mut b, s, a);
            }
        }
        b
    }

    /// Moves every point by `d` (and the axis with it).
    pub fn translate(mut self, d: DVec3) -> Model {
        for s in &mut self.steps {
            match s {
                Step::String(st) => {
                    st.start += d;
                    st.end += d;
                    if let Some(a) = &mut st.arc {
                        a.center_xy[0] += d.x;
                        a.center_xy[1] += d.y;
                    }
                }
                Step::Travel { to, .. } => *to += d,
                Step::Marker { z_mm, .. } => *z_mm += d.z,
                _ => {}
            }
        }
        self.axis_xy[0] += d.x;
        self.axis_xy[1] += d.y;
        self
    }

    /// Mirrors every point in XY about the line through `a` and `b` (Z kept; arcs change
    /// direction). The caller checks `a != b` in XY.
    pub fn reflect_xy(mut self, a: DVec3, b: DVec3) -> Model {
        let dir = (b - a).truncate().normalize_or_zero();
        let r = |p: DVec3| {
            let v = (p - a).truncate();
            let q = a.truncate() + dir * (2.0 * v.dot(dir)) - v;
            DVec3::new(q.x, q.y, p.z)
        };
        for s in &mut self.steps {
            match s {
                Step::String(st) => {
                    st.start = r(st.start);
                    st.end = r(st.end);
                    if let Some(arc) = &mut st.arc {
                        let c = r(DVec3::new(arc.center_xy[0], arc.center_xy[1], 0.0));
                        arc.center_xy = [c.x, c.y];
                        arc.ccw = !arc.ccw;
                    }
                }
                Step::Travel { to, .. } => *to = r(*to),
                _ => {}
            }
        }
        let ax = r(DVec3::new(self.axis_xy[0], self.axis_xy[1], 0.0));
        self.axis_xy = [ax.x, ax.y];
        self
    }

    /// Maps every string's cross-section and speed (keeps geometry).
    pub fn map_strings(mut self, mut f: impl FnMut(usize, &mut Str)) -> Model {
        let mut i = 0;
        for s in &mut self.steps {
            if let Step::String(st) = s {
                f(i, st);
                i += 1;
            }
        }
        self
    }

    /// Partitioning: splits the model into the steps whose predicate is true and the rest,
    /// keeping order inside each. Markers and state changes go with the strings that follow
    /// them (to the `true` side if the next string is true).
    pub fn partition(self, mut pred: impl FnMut(&Step) -> bool) -> (Model, Model) {
        let mut yes = Model::new(self.axis_xy);
        let mut no = Model::new(self.axis_xy);
        yes.emission = self.emission;
        no.emission = self.emission;
        let mut pending: Vec<Step> = Vec::new();
        for s in self.steps {
            match &s {
                Step::String(_) | Step::Travel { .. } => {
                    let dest = if pred(&s) { &mut yes } else { &mut no };
                    dest.steps.append(&mut pending);
                    dest.steps.push(s);
                }
                _ => pending.push(s),
            }
        }
        no.steps.append(&mut pending);
        (yes, no)
    }

    /// Splits the model into parts at every marker of `kind` (each part starts with its
    /// marker); steps before the first marker form the first part.
    pub fn split_at_markers(self, kind: MarkerKind) -> Vec<Model> {
        let mut parts = Vec::new();
        let mut cur = Model::new(self.axis_xy);
        cur.emission = self.emission;
        for s in self.steps {
            if matches!(&s, Step::Marker { kind: k, .. } if *k == kind) && !cur.steps.is_empty() {
                let next = Model {
                    steps: Vec::new(),
                    axis_xy: cur.axis_xy,
                    emission: cur.emission,
                };
                parts.push(std::mem::replace(&mut cur, next));
            }
            cur.steps.push(s);
        }
        if !cur.steps.is_empty() {
            parts.push(cur);
        }
        parts
    }

    /// Reordering: assembles `parts` in the order given by `order` (indices into `parts`;
    /// an index out of range is an error, a part may not repeat).
    pub fn reorder_parts(parts: Vec<Model>, order: &[usize]) -> Result<Model, String> {
        let mut slots: Vec<Option<Model>> = parts.into_iter().map(Some).collect();
        let mut out = Vec::with_capacity(order.len());
        for &i in order {
            let p = slots
                .get_mut(i)
                .ok_or_else(|| format!("part index {i} out of range"))?
                .take()
                .ok_or_else(|| format!("part {i} used twice"))?;
            out.push(p);
        }
        Ok(Model::assemble(out))
    }

    /// Splits every straight string longer than `max_len_mm` into equal strings no longer
    /// than it (same cross-section and speed), so later deformations bend it smoothly. Arcs
    /// are kept. Errors when the result would exceed [`MAX_STRINGS`].
    pub fn subdivide(mut self, max_len_mm: f64) -> Result<Model, String> {
        if !(max_len_mm.is_finite() && max_len_mm > 0.0) {
            return Err(format!(
                "subdivide: max length must be > 0, got {max_len_mm}"
            ));
        }
        let limit = MAX_STRINGS as f64;
        let total: f64 = self
            .strings()
            .filter(|s| s.arc.is_none())
            .map(|s| (s.len_mm() / max_len_mm).ceil().max(1.0))
            .sum();
        if total > limit {
            return Err(format!(
                "subdivide: {total:.0} strings at max length {max_len_mm} mm (limit {limit:.0})"
            ));
        }
        let mut out = Vec::with_capacity(total as usize + self.steps.len());
        for step in self.steps.drain(..) {
            match step {
                Step::String(s) if s.arc.is_none() && s.len_mm() > max_len_mm => {
                    let n = (s.len_mm() / max_len_mm).ceil() as usize;
                    let mut prev = s.start;
                    for k in 1..=n {
                        let p = if k == n {
                            s.end
                        } else {
                            s.start.lerp(s.end, k as f64 / n as f64)
                        };
                        out.push(Step::String(Str::line(prev, p, s.cross_mm2, s.speed_mm_s)));
                        prev = p;
                    }
                }
                other => out.push(other),
            }
        }
        self.steps = out;
        Ok(self)
    }

    /// Sets the emission thinning length (see [`EmissionHints::thin_min_len_mm`]).
    pub fn thin_at_emission(mut self, min_len_mm: f64) -> Model {
        self.emission.thin_min_len_mm = (min_len_mm > 0.0).then_some(min_len_mm);
        self
    }

    /// Replaces every arc string by straight strings whose chord deviates from the arc by at
    /// most `tol_mm`.
    pub fn arcs_to_lines(mut self, tol_mm: f64) -> Model {
        if !self.strings().any(|s| s.arc.is_some()) {
            return self;
        }
        let mut out = Vec::with_capacity(self.steps.len());
        for s in self.steps.drain(..) {
            match s {
                Step::String(st) if st.arc.is_some() => {
                    for piece in arc_to_lines(&st, tol_mm) {
                        out.push(Step::String(piece));
                    }
                }
                other => out.push(other),
            }
        }
        self.steps = out;
        self
    }
}

/// Straight strings approximating an arc string within `tol_mm` of chord deviation.
pub fn arc_to_lines(st: &Str, tol_mm: f64) -> Vec<Str> {
    let Some(a) = st.arc else {
        return vec![*st];
    };
    let c = glam::DVec2::from(a.center_xy);
    let r = (st.start.truncate() - c).length();
    let sweep = arc_sweep_rad(st.start, st.end, a);
    let tol = tol_mm.max(1e-4);
    // sagitta r(1 − cos(φ/2)) ≤ tol  ⇒  φ ≤ 2 acos(1 − tol/r)
    let max_phi = if r <= tol {
        std::f64::consts::PI
    } else {
        2.0 * (1.0 - tol / r).clamp(-1.0, 1.0).acos()
    };
    let n = ((sweep.abs() / max_phi.max(1e-6)).ceil() as usize).clamp(1, 100_000);
    let a0 = (st.start.truncate() - c).to_angle();
    let r_end = (st.end.truncate() - c).length();
    let mut prev = st.start;
    let mut out = Vec::with_capacity(n);
    for k in 1..=n {
        let t = k as f64 / n as f64;
        let p = if k == n {
            st.end
        } else {
            let ang = a0 + sweep * t;
            let rr = r + (r_end - r) * t;
            DVec3::new(
                c.x + rr * ang.cos(),
                c.y + rr * ang.sin(),
                st.start.z + (st.end.z - st.start.z) * t,
            )
        };
        out.push(Str::line(prev, p, st.cross_mm2, st.speed_mm_s));
        prev = p;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(a: [f64; 3], b: [f64; 3]) -> Step {
        Step::String(Str::line(a.into(), b.into(), 0.2, 20.0))
    }

    /// Assembly never travels through a printed part: from the end of a 10 mm tower the head
    /// rises above the tower's top, crosses, and comes down onto the next part.
    #[test]
    fn assembly_lifts_over_printed_parts() {
        let mut tower = Model::new([0.0, 0.0]);
        for k in 0..50 {
            let z = 0.2 * (k + 1) as f64;
            tower.push(s([0., 0., z], [2., 0., z]));
        }
        let mut next = Model::new([0.0, 0.0]);
        next.push(s([-10., 0., 0.2], [-12., 0., 0.2]));
        let m = Model::assemble([tower, next]);
        let travels: Vec<DVec3> = m
            .steps
            .iter()
            .filter_map(|st| match st {
                Step::Travel { to, .. } => Some(*to),
                _ => None,
            })
            .collect();
        assert_eq!(
            travels,
            [
                DVec3::new(2.0, 0.0, 11.0),
                DVec3::new(-10.0, 0.0, 11.0),
                DVec3::new(-10.0, 0.0, 0.2)
            ]
        );
        // Joined parts get no travel.
        let mut a = Model::new([0.0, 0.0]);
        a.push(s([0., 0., 0.2], [1., 0., 0.2]));
        let mut b = Model::new([0.0, 0.0]);
        b.push(s([1., 0., 0.2], [2., 0., 0.2]));
        let j = Model::assemble([a, b]);
        assert!(j.steps.iter().all(|st| !matches!(st, Step::Travel { .. })));
    }

    #[test]
    fn assembly_keeps_order_and_partition_splits() {
        let mut a = Model::new([0.0, 0.0]);
        a.push(s([0., 0., 0.2], [1., 0., 0.2]));
        let mut b = Model::new([0.0, 0.0]);
        b.push(Step::Comment("b".into()));
        b.push(s([5., 0., 0.2], [6., 0., 0.2]));
        let m = a.then(b);
        assert_eq!(m.string_count(), 2);
        let (left, right) = m.partition(|st| match st {
            Step::String(s) => s.start.x < 3.0,
            _ => false,
        });
        assert_eq!(left.string_count(), 1);
        assert_eq!(right.string_count(), 1);
        assert!(matches!(right.steps[0], Step::Comment(_)));
    }

    #[test]
    fn reorder_rejects_bad_indices() {
        let parts = vec![Model::default(), Model::default()];
        assert!(Model::reorder_parts(parts.clone(), &[2]).is_err());
        assert!(Model::reorder_parts(parts.clone(), &[0, 0]).is_err());
        assert!(Model::reorder_parts(parts, &[1, 0]).is_ok());
    }

    #[test]
    fn arc_length_and_subdivision() {
        let st = Str {
            start: DVec3::new(10.0, 0.0, 0.0),
            end: DVec3::new(0.0, 10.0, 0.0),
            cross_mm2: 0.2,
            speed_mm_s: 10.0,
            arc: Some(Arc {
                center_xy: [0.0, 0.0],
                ccw: true,
            }),
        };
        let quarter = std::f64::consts::FRAC_PI_2 * 10.0;
        assert!((st.len_mm() - quarter).abs() < 1e-9);
        let lines = arc_to_lines(&st, 0.01);
        assert!(lines.len() > 5);
        let total: f64 = lines.iter().map(Str::len_mm).sum();
        assert!((total - quarter).abs() < 0.05);
        assert_eq!(lines.last().map(|l| l.end), Some(st.end));
    }
}
