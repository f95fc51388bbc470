//! The comment-free rule: layers from the heights at which extruding moves print, and the
//! turns of a continuous spiral from the path itself (docs/planner.md, "What a layer is";
//! docs/planner.md, "Layers of a continuous spiral").
//!
//! A layer is a set of extrusions that belong together in height, not every change of Z.
//! Between two consecutive extruding moves a layer starts when
//! - the second starts **higher** than the layer printed so far (a flat layer change; a Z-hop
//!   comes back down before the next extrusion, so it starts none);
//! - the second starts **lower** (sequential printing: the next object's first layer);
//! - the second **rises** while it prints after flat layers: a spiral (vase mode, helical
//!   prints) begins; its first turn is a layer. Never before the job's first layer has printed
//!   a loop whole (every slicer prints a vase's bottom flat; on a levelled bed the first rise
//!   comes within the first loop), unless the job's very first extrusion rises (a helix);
//! - inside a spiral, the head has come round: a **turn ends** at the point of the path
//!   closest to where the turn began (within [`TURN_CLOSE_UM`] of it, after having gone at
//!   least [`TURN_AWAY_UM`] away and risen at least 3/5 of the expected rise of a turn — the
//!   last turn's rise, or a quarter of the layer height for the first turn), which is where
//!   the slicers put their own marker: the seam, where Z reaches the layer's height. A spiral
//!   whose turns never come back within [`TURN_CLOSE_UM`] is cut every 3/2 of the expected
//!   rise instead (a first turn that has gone away waits for its seam up to 3 times the
//!   layer height: its rise is not known yet).
//!
//! **Levelling baked into the file** (MatterControl's software levelling: every move cut into
//! short pieces, each with its own Z): an extruding move that falls, or rises where no spiral
//! can begin, makes the job *levelled*. From then on "higher" and "lower" are measured from the
//! lowest extrusion of the layer so far, beyond half a layer height ([`Heights::tolerance`]),
//! and no spiral is looked for (a levelled vase is not recognised). This holds while the bed's
//! deviation over the print is less than half a layer height.
//!
//! **What prints before the first layer** (a purge line in the start code) is a prelude, no
//! layer: the count restarts at the first layer ([`Start::Restart`]) when, before anything has
//! risen, the job's first layer so far is
//! - left **downwards** (a purge above the first layer: Cura's Ender-3 start code), or
//! - a **line** — extrusions drawn in one go (each within [`TURN_CLOSE_UM`] of where the last
//!   ended), at least [`PURGE_MIN_UM`] long, inside a strip at most [`LINE_WIDTH_UM`] wide — and
//!   the next extrusion starts **higher** (a purge below the first
//!   layer) or at its height **away from the line** (more than [`TURN_CLOSE_UM`] from it: a
//!   purge at the first layer's height). No object's first layer starts as an isolated line:
//!   it starts with a skirt, a brim or a wall, each a loop.
//!
//! The first extruding move starts the first layer. Heights and positions are the commanded
//! ones in µm (the G-code's own resolution: a vase move that rises 1 µm rises, though it makes
//! no Z step), so a spiral is seen from its first move.

/// Heights of a flat (not levelled) job compare exactly, µm (slicers write Z with 3 decimals).
const TOL_UM: i32 = 0;

/// The layer height assumed before any is known: the first layer's own height, at least this.
const MIN_LAYER_UM: i32 = 100;

/// A spiral turn closes where the head comes back within this distance of the turn's start
/// (XY), µm. The slicers' seam moves from one turn to the next by the change of the shape
/// (measured: 0.0–0.3 mm on PrusaSlicer's and Cura's twisted vases).
pub const TURN_CLOSE_UM: i64 = 2_000;

/// ... after having gone at least this far from it, µm.
pub const TURN_AWAY_UM: i64 = 2 * TURN_CLOSE_UM;

/// A purge line lies inside a strip at most this wide, µm (Cura's two lines 0.3 mm apart;
/// PrusaSlicer's, BambuStudio's and Creality's single lines along one axis).
pub const LINE_WIDTH_UM: i32 = 2_000;

/// ... and extrudes along at least this much path, µm (the shortest start-code purge in the
/// corpus is 40 mm).
pub const PURGE_MIN_UM: i64 = 20_000;

/// Whether an extruding move starts a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Start {
    /// It continues the current layer.
    Same,
    /// A new layer starts before it.
    Layer,
    /// A new layer starts before it, and what came before was a prelude (a purge line): the
    /// count restarts at the first layer.
    Restart,
}

/// The spiral turn being printed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Turn {
    /// Where the turn began (X, Y), µm.
    start_xy: [i32; 2],
    /// Height where it began, µm.
    base_um: i32,
    /// The head has been at least [`TURN_AWAY_UM`] from the start.
    away: bool,
    /// Expected rise of a turn, µm: the last turn's rise, or the layer height for the first.
    rise_um: i32,
    /// The spiral's first turn (its rise is not known yet).
    first: bool,
}

impl Turn {
    fn new(start: &[i32; 3], rise_um: i32, first: bool) -> Self {
        Turn {
            start_xy: [start[0], start[1]],
            base_um: start[2],
            away: false,
            rise_um: rise_um.max(1),
            first,
        }
    }

    /// Rise after which a turn without a seam is cut: 3/2 of the expected rise — or 3 times
    /// it for a first turn that has gone away from its start (it may still come round, and
    /// its rise is not known yet: a helix may rise more per turn than its first layer is
    /// high, as the host compiler's 0.4 mm-pitch helix from Z 0.2 does).
    fn cut_um(&self) -> i32 {
        let halves = if self.first && self.away { 6 } else { 3 };
        self.rise_um.saturating_mul(halves) / 2
    }

    /// Squared XY distance from the turn's start, µm².
    fn dist2(&self, p: &[i32; 3]) -> i64 {
        let dx = i64::from(p[0]) - i64::from(self.start_xy[0]);
        let dy = i64::from(p[1]) - i64::from(self.start_xy[1]);
        dx * dx + dy * dy
    }

    /// Whether the turn ends at `a`, the start of the move `a → b`: back near the turn's
    /// start after going round, and `b` no closer (so `a` is the closest point).
    fn closes_at(&self, a: &[i32; 3], b: &[i32; 3]) -> bool {
        let gate = if self.first {
            self.rise_um / 4
        } else {
            self.rise_um * 3 / 5
        };
        let da = self.dist2(a);
        self.away
            && a[2].saturating_sub(self.base_um) >= gate
            && da <= TURN_CLOSE_UM * TURN_CLOSE_UM
            && self.dist2(b) >= da
    }
}

/// A flat layer printed as one loop so far: contiguous extrusions from `start_xy`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Lap {
    start_xy: [i32; 2],
    end_xy: [i32; 2],
    /// The head has been at least [`TURN_AWAY_UM`] from the start.
    away: bool,
    /// An extrusion started elsewhere than where the last one ended: not one loop.
    broken: bool,
    /// The path has come back within [`TURN_CLOSE_UM`] of its start after going away: a loop
    /// was printed whole.
    looped: bool,
}

impl Lap {
    /// The layer has printed more than part of its first loop (a loop whole, or pieces in
    /// several places): a spiral may begin after it, levelling's rises come before.
    fn complete(&self) -> bool {
        self.broken || self.looped
    }

    fn dist2(&self, p: &[i32; 2]) -> i64 {
        let dx = i64::from(p[0]) - i64::from(self.start_xy[0]);
        let dy = i64::from(p[1]) - i64::from(self.start_xy[1]);
        dx * dx + dy * dy
    }

    /// One closed loop, and the next extrusion starts at `a`, near where it closed (Cura may
    /// travel a fraction of a millimetre to the spiral's start).
    fn closed_at(&self, a: &[i32; 3]) -> bool {
        let dx = i64::from(a[0]) - i64::from(self.end_xy[0]);
        let dy = i64::from(a[1]) - i64::from(self.end_xy[1]);
        !self.broken
            && self.away
            && dx * dx + dy * dy <= TURN_CLOSE_UM * TURN_CLOSE_UM
            && self.dist2(&self.end_xy) <= TURN_CLOSE_UM * TURN_CLOSE_UM
    }
}

/// The job's first layer while it is one line: its XY extent and extruded path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Line {
    min_xy: [i32; 2],
    max_xy: [i32; 2],
    /// Extruded path, µm (saturating: a purge is tens of mm).
    len_um: i32,
}

impl Line {
    fn at(a: &[i32; 3]) -> Self {
        Line {
            min_xy: [a[0], a[1]],
            max_xy: [a[0], a[1]],
            len_um: 0,
        }
    }

    /// The line with the extrusion `a → b`, which starts `jump2` (µm²) from where the last
    /// one ended; `None` once it is wider than a line, or once an extrusion starts more than
    /// [`TURN_CLOSE_UM`] from where the last one ended (a line is drawn in one go: Cura's two
    /// purge lines are 0.3 mm apart).
    fn with(mut self, a: &[i32; 3], b: &[i32; 3], jump2: i64) -> Option<Self> {
        if jump2 > TURN_CLOSE_UM * TURN_CLOSE_UM {
            return None;
        }
        for p in [a, b] {
            for ((lo, hi), v) in self.min_xy.iter_mut().zip(&mut self.max_xy).zip(p) {
                *lo = (*lo).min(*v);
                *hi = (*hi).max(*v);
            }
        }
        let dx = i64::from(b[0]) - i64::from(a[0]);
        let dy = i64::from(b[1]) - i64::from(a[1]);
        let piece = i32::try_from(isqrt(dx * dx + dy * dy)).unwrap_or(i32::MAX);
        self.len_um = self.len_um.saturating_add(piece);
        let w = |k: usize| i64::from(self.max_xy[k]) - i64::from(self.min_xy[k]);
        (w(0).min(w(1)) <= i64::from(LINE_WIDTH_UM)).then_some(self)
    }

    /// Long enough to be a purge.
    fn purge(&self) -> bool {
        i64::from(self.len_um) >= PURGE_MIN_UM
    }

    /// `p` lies more than [`TURN_CLOSE_UM`] outside the line's extent.
    fn away_from(&self, p: &[i32; 3]) -> bool {
        (0..2).any(|k| {
            i64::from(p[k]) < i64::from(self.min_xy[k]) - TURN_CLOSE_UM
                || i64::from(p[k]) > i64::from(self.max_xy[k]) + TURN_CLOSE_UM
        })
    }
}

/// Integer square root (floor) of a non-negative number.
fn isqrt(v: i64) -> i64 {
    if v <= 0 {
        return 0;
    }
    let mut x = libm::sqrt(v as f64) as i64;
    while x > 0 && x * x > v {
        x -= 1;
    }
    while (x + 1) * (x + 1) <= v {
        x += 1;
    }
    x
}

/// What the current layer is being printed as.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Shape {
    /// Nothing known yet, or a levelled layer (its lap is not followed).
    #[default]
    Unknown,
    /// A flat layer, and its path so far.
    Flat(Lap),
    /// A spiral, and the turn being printed.
    Spiral(Turn),
}

impl Shape {
    fn turn(&self) -> Option<Turn> {
        match self {
            Shape::Spiral(t) => Some(*t),
            _ => None,
        }
    }

    fn lap(&self) -> Option<Lap> {
        match self {
            Shape::Flat(l) => Some(*l),
            _ => None,
        }
    }
}

/// Extrusion heights and the spiral turn seen so far (bounded: a few numbers).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Heights {
    /// Z at the end of the last extruding move, µm.
    last_end_um: Option<i32>,
    /// Lowest Z of the current flat (or levelled) layer's extrusions, µm.
    layer_min_um: Option<i32>,
    /// Height (lowest Z) of the last flat layer, µm.
    flat_um: Option<i32>,
    /// Last step between flat layers (or the first layer's height), µm.
    step_um: Option<i32>,
    /// Layers this rule has started (saturating at 2: the prelude rules ask for exactly 1).
    layers: u8,
    /// A layer has started above the one before (the prelude rules apply only before that).
    rose: bool,
    /// Extruding moves change Z outside spirals: levelling baked into the file.
    levelled: bool,
    /// What is being printed: a flat layer (its lap) or a spiral (its turn).
    shape: Shape,
    /// The job's first layer, while it is one line (a purge line, maybe).
    line: Option<Line>,
}

impl Heights {
    pub(super) const fn new() -> Self {
        Heights {
            last_end_um: None,
            layer_min_um: None,
            flat_um: None,
            step_um: None,
            layers: 0,
            rose: false,
            levelled: false,
            shape: Shape::Unknown,
            line: None,
        }
    }

    /// How far heights may differ and still be one layer, µm: exact for a flat job, half a
    /// layer height for a levelled one.
    fn tolerance(&self) -> i32 {
        if self.levelled {
            self.step_um.unwrap_or(MIN_LAYER_UM).max(MIN_LAYER_UM) / 2
        } else {
            TOL_UM
        }
    }

    /// Before anything rose, the job's first layer so far is a purge line.
    fn purge_line(&self) -> bool {
        !self.rose && self.layers == 1 && self.line.is_some_and(|l| l.purge())
    }

    /// An extruding move from `a` to `b` (X, Y, Z in µm): whether it starts a layer.
    pub(super) fn extrusion(&mut self, a: &[i32; 3], b: &[i32; 3]) -> Start {
        let rising = b[2] > a[2];
        let Some(last) = self.last_end_um else {
            self.begin(a, rising);
            self.moved_to(a, b);
            return Start::Layer;
        };
        // A spiral never falls, and none begins before the first layer has printed a loop
        // whole (every slicer prints a vase's bottom flat; on a levelled bed the first rise
        // comes within the first loop): such a change of Z while printing is levelling (a first
        // turn so far is the same layer, levelled).
        let may_spiral =
            !self.levelled && (self.layers >= 2 || self.shape.lap().is_some_and(|l| l.complete()));
        let changes_z = b[2] < a[2] || (rising && self.shape.turn().is_none() && !may_spiral);
        if changes_z && !self.levelled && self.shape.turn().is_none_or(|t| t.first) {
            self.levelled = true;
            if let Shape::Spiral(t) = self.shape {
                self.layer_min_um = Some(t.base_um.min(a[2]));
                self.shape = Shape::Unknown;
            }
        }
        let tol = self.tolerance();
        let base = if self.levelled {
            self.layer_min_um.unwrap_or(last)
        } else {
            last
        };
        let start = match self.shape.turn() {
            _ if a[2] < base.saturating_sub(tol) => {
                // Lower: the next object of a sequential print, or the end of a prelude.
                if !self.rose && self.layers == 1 {
                    Start::Restart
                } else {
                    Start::Layer
                }
            }
            None if a[2] > base.saturating_add(tol) => {
                if self.purge_line() {
                    Start::Restart
                } else {
                    Start::Layer
                }
            }
            None if self.purge_line() && self.line.is_some_and(|l| l.away_from(a)) => {
                Start::Restart
            }
            // A flat layer above the spiral.
            Some(_) if !rising && a[2] > last.saturating_add(tol) => Start::Layer,
            Some(t) if t.closes_at(a, b) => {
                // The next turn; its expected rise is the one just completed.
                let rise = a[2].saturating_sub(t.base_um).max(1);
                return self.next_turn(Turn::new(a, rise, false), a, b);
            }
            Some(t) if a[2].saturating_sub(t.base_um) >= t.cut_um() => {
                // No seam found: cut by height, the expected rise kept.
                return self.next_turn(Turn::new(a, t.rise_um, t.first), a, b);
            }
            Some(_) => Start::Same,
            None if rising
                && may_spiral
                && a[2] == last
                && self.shape.lap().is_some_and(|l| l.closed_at(a)) =>
            {
                // Cura's first spiralized layer prints its wall once flat, then spirals on
                // from where the loop closed: the first turn is the same layer.
                self.rose = true;
                let h = self.step_um.unwrap_or(MIN_LAYER_UM);
                self.shape = Shape::Spiral(Turn::new(a, h, true));
                Start::Same
            }
            None if rising && may_spiral => Start::Layer,
            None => Start::Same,
        };
        match start {
            Start::Same => {}
            Start::Restart => {
                *self = Heights::new();
                self.begin(a, rising);
            }
            Start::Layer => self.begin(a, rising),
        }
        self.moved_to(a, b);
        start
    }

    /// The head went on from `a` to `b`.
    fn moved_to(&mut self, a: &[i32; 3], b: &[i32; 3]) {
        if let Shape::Spiral(t) = &mut self.shape {
            if t.dist2(b) >= TURN_AWAY_UM * TURN_AWAY_UM {
                t.away = true;
            }
        }
        // How far this extrusion starts from where the last one ended (the flat layer's lap
        // knows; the first layer is flat while it may be a line).
        let jump2 = self.shape.lap().map_or(0, |l| {
            let dx = i64::from(a[0]) - i64::from(l.end_xy[0]);
            let dy = i64::from(a[1]) - i64::from(l.end_xy[1]);
            dx * dx + dy * dy
        });
        self.line = self.line.and_then(|l| l.with(a, b, jump2));
        if let Shape::Flat(l) = &mut self.shape {
            if l.end_xy != [a[0], a[1]] {
                l.broken = true;
            }
            l.end_xy = [b[0], b[1]];
            let d2 = l.dist2(&l.end_xy);
            if d2 >= TURN_AWAY_UM * TURN_AWAY_UM {
                l.away = true;
            } else if l.away && d2 <= TURN_CLOSE_UM * TURN_CLOSE_UM {
                l.looped = true;
            }
        }
        if self.shape.turn().is_none() {
            let low = a[2].min(b[2]);
            self.layer_min_um = Some(self.layer_min_um.map_or(low, |m| m.min(low)));
        }
        self.last_end_um = Some(b[2]);
    }

    /// A spiral's next turn starts (at `t`'s start; the move goes on to `b`).
    fn next_turn(&mut self, t: Turn, a: &[i32; 3], b: &[i32; 3]) -> Start {
        self.layers = 2;
        self.shape = Shape::Spiral(t);
        self.moved_to(a, b);
        Start::Layer
    }

    /// A layer starts at `a`: flat, or the first turn of a spiral.
    fn begin(&mut self, a: &[i32; 3], rising: bool) {
        let first_layer = self.layers == 0;
        // The last flat layer's height: the layer just printed, unless it was a spiral.
        let below = match self.shape.turn() {
            Some(_) => self.flat_um,
            None => self.layer_min_um.or(self.flat_um),
        };
        self.layers = self.layers.saturating_add(1).min(2);
        if let Some(last) = self.last_end_um {
            if a[2] > last.saturating_add(self.tolerance()) {
                self.rose = true;
            }
        }
        if first_layer {
            // Its height stands for the layer height until a step between layers is seen.
            self.step_um = Some(a[2].max(MIN_LAYER_UM));
        }
        self.line = (first_layer && !rising).then(|| Line::at(a));
        if rising && !self.levelled {
            self.rose = true;
            let h = self.step_um.unwrap_or(MIN_LAYER_UM);
            self.shape = Shape::Spiral(Turn::new(a, h, true));
            self.layer_min_um = None;
        } else {
            self.shape = Shape::Flat(Lap {
                start_xy: [a[0], a[1]],
                end_xy: [a[0], a[1]],
                away: false,
                broken: false,
                looped: false,
            });
            if let Some(f) = below {
                if a[2] > f.saturating_add(self.tolerance()) {
                    self.step_um = Some(a[2].saturating_sub(f));
                }
            }
            self.flat_um = Some(a[2]);
            self.layer_min_um = Some(a[2]);
        }
    }

    /// A job continued part-way (after a power cut): no prelude to look for.
    pub(super) fn no_prelude(&mut self) {
        self.rose = true;
        // Not the print's first layer: its height says nothing about the layer height.
        self.layers = 2;
    }

    /// True once an extruding move has been seen.
    pub(super) fn printed(&self) -> bool {
        self.last_end_um.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::{Heights, Start};
    use std::vec::Vec;

    /// Feed (start, end) heights of moves along X; the indexes of the moves that start layers
    /// (restarts marked negative).
    fn layers(moves: &[(i32, i32)]) -> Vec<i64> {
        let mut h = Heights::new();
        let mut x = 0;
        (0..moves.len())
            .filter_map(|i| {
                let (a, b) = ([x, 0, moves[i].0], [x + 1000, 0, moves[i].1]);
                x += 1000;
                match h.extrusion(&a, &b) {
                    Start::Same => None,
                    Start::Layer => Some(i as i64),
                    Start::Restart => Some(-(i as i64)),
                }
            })
            .collect()
    }

    #[test]
    fn flat_layers_hops_and_sequential_drops() {
        // 0.3, 0.3 (a hop came back down), 0.6, then a second object back at 0.3.
        assert_eq!(
            layers(&[
                (300, 300),
                (300, 300),
                (600, 600),
                (600, 600),
                (300, 300),
                (600, 600)
            ]),
            vec![0, 2, 4, 5]
        );
    }

    #[test]
    fn a_purge_line_above_the_first_layer_is_a_prelude() {
        // Cura's Ender-3 purge at 0.28, the first layer at 0.2: the count restarts there.
        assert_eq!(
            layers(&[(280, 280), (280, 280), (200, 200), (400, 400), (200, 200)]),
            vec![0, -2, 3, 4]
        );
    }

    /// A circle of `n` points of radius `r` µm around (50 mm, 50 mm), point `k`.
    fn on_circle(k: usize, n: usize, r: f64) -> [i32; 2] {
        let a = core::f64::consts::TAU * (k % n) as f64 / n as f64;
        [50_000 + (r * a.cos()) as i32, 50_000 + (r * a.sin()) as i32]
    }

    #[test]
    fn a_spiral_turn_ends_where_it_began() {
        // Two flat layers of 200 µm, then a spiral of 40-point turns rising 200 µm per turn.
        let mut h = Heights::new();
        let n = 40;
        let xy = |k| on_circle(k, n, 20_000.0);
        // A flat layer: the wall, then (after a travel) a line of infill.
        let flat = |h: &mut Heights, z: i32| {
            let mut s = Vec::new();
            for k in 0..n {
                let (a, b) = (xy(k), xy(k + 1));
                s.push(h.extrusion(&[a[0], a[1], z], &[b[0], b[1], z]));
            }
            s.push(h.extrusion(&[45_000, 50_000, z], &[55_000, 50_000, z]));
            s.push(h.extrusion(&[55_000, 51_000, z], &[xy(0)[0], xy(0)[1], z]));
            s
        };
        // One bottom layer only (the loop and a line of infill), then the spiral: its first
        // rise is a spiral's, not levelling (the bottom printed its loop whole).
        let mut one = Heights::new();
        assert_eq!(flat(&mut one, 200)[0], Start::Layer);
        let mut starts = Vec::new();
        for k in 0..(n * 3) {
            let z = |k: usize| 200 + (k * 200 / n) as i32;
            let (a, b) = (xy(k), xy(k + 1));
            if one.extrusion(&[a[0], a[1], z(k)], &[b[0], b[1], z(k + 1)]) != Start::Same {
                starts.push(k);
            }
        }
        assert_eq!(starts, vec![0, n, 2 * n]);
        assert!(!one.levelled);
        assert_eq!(flat(&mut h, 200)[0], Start::Layer);
        assert_eq!(flat(&mut h, 400)[0], Start::Layer);
        let mut starts = Vec::new();
        for k in 0..(n * 5) {
            let z = |k: usize| 400 + (k * 200 / n) as i32;
            let (a, b) = (xy(k), xy(k + 1));
            if h.extrusion(&[a[0], a[1], z(k)], &[b[0], b[1], z(k + 1)]) != Start::Same {
                starts.push(k);
            }
        }
        assert_eq!(starts, vec![0, n, 2 * n, 3 * n, 4 * n]);
        // Cura's first spiralized layer: its wall printed once flat (one closed loop), then the
        // spiral from where the loop closed: the first turn is the same layer.
        let mut h = Heights::new();
        flat(&mut h, 200);
        let mut starts = Vec::new();
        for k in 0..(n * 3) {
            let z = |k: usize| {
                if k < n {
                    400
                } else {
                    400 + ((k - n) * 200 / n) as i32
                }
            };
            let (a, b) = (xy(k), xy(k + 1));
            if h.extrusion(&[a[0], a[1], z(k)], &[b[0], b[1], z(k + 1)]) != Start::Same {
                starts.push(k);
            }
        }
        assert_eq!(starts, vec![0, 2 * n]);
    }
}
