//! Judging where a `layer` pause stopped, against the independent reference model
//! (`layerref`, which shares no code with the firmware's layer detector): used by the layer
//! corpus and marker-family tests.
//!
//! A run's stop is found in its executed records (the last job block before the first service
//! block after the request); it is at a layer boundary when every extrusion of the reference's
//! layer k has run and none of layer k+1's (moves between them may fall on either side). The
//! boundary must be the **first reachable** one (docs/planner.md): not passed at the request,
//! and not beyond the first boundary whose end of extrusion lies farther along the path than
//! the braking distance `v²/2a` from the speed at the request plus [`REACH_MARGIN_MM`].

use layerref::read::{Item, Reader};
use layerref::{Comments, Model};
use sim::exec::PrinterFactory;
use sim::hostlink::Origin;
use sim::port::Lane;
use sim::run::{self, Mode, Policy, Scenario};

/// Margin of the reachable bound, mm (the executing segment, the speed estimate, the speed-up
/// a request starts; as `sim::metrics::REACH_MARGIN_MM`).
pub const REACH_MARGIN_MM: f64 = 2.0;

/// A run's outcome with the firmware executive.
pub type Outcome = run::Outcome<<PrinterFactory as run::Factory>::Exec>;

/// A job as the host sends it, with its reference layers.
pub struct Job {
    /// The lines (comments in them; the host strips them when `comments` is `Strip`).
    pub lines: Vec<String>,
    /// Comments kept or stripped on the link.
    pub comments: Comments,
    /// The reference model of the stream the printer receives.
    pub model: Model,
    /// Path length (XYZ, mm) from the start of the job to the end of each line.
    pub path_end_mm: Vec<f64>,
    /// The printer it runs on (the Ender-3 unless a test says otherwise).
    pub machine: firmware::config::MachineConfig,
    /// Let E move cold (the file heats in a start-code macro the sim cannot run).
    pub allow_cold: bool,
    /// Virtual time simulated after a request, µs: enough to stop at the end of the longest
    /// layer, park and resume (a minute for the generated corpus' small layers).
    pub after_request_us: u64,
}

impl Job {
    /// `lines` sent with comments kept or stripped.
    pub fn new(lines: Vec<String>, comments: Comments) -> Job {
        let model = Model::of_lines(lines.iter().map(String::as_str), comments);
        let mut r = Reader::default();
        let mut path = 0.0;
        let path_end_mm = lines
            .iter()
            .map(|l| {
                if let Item::Move { from, to } = r.line(l, comments == Comments::Strip) {
                    path += (0..3)
                        .map(|k| (to[k] - from[k]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                }
                path
            })
            .collect();
        Job {
            lines,
            comments,
            model,
            path_end_mm,
            machine: firmware::config::MachineConfig::ENDER3,
            allow_cold: false,
            after_request_us: 60_000_000,
        }
    }

    /// The firmware policy with the link keeping or stripping comments.
    pub fn scenario(&self) -> Scenario {
        let mut sc = Scenario::new(Policy::Firmware, Mode::Layer);
        sc.link.strip_comments = self.comments == Comments::Strip;
        sc.machine = self.machine;
        sc.allow_cold = self.allow_cold;
        sc
    }

    /// Index of the layer of the last extrusion at or before line `i`.
    pub fn layer_before(&self, i: usize) -> Option<usize> {
        (0..=i.min(self.lines.len().saturating_sub(1)))
            .rev()
            .find_map(|k| self.model.layer_index(k))
    }

    /// Index of the layer of the first extrusion at or after line `i`.
    pub fn layer_after(&self, i: usize) -> Option<usize> {
        (i..self.lines.len()).find_map(|k| self.model.layer_index(k))
    }

    /// The last extruding line of layer `k`.
    pub fn last_line_of(&self, k: usize) -> Option<usize> {
        self.model.layers().get(k).map(|l| l.last_line)
    }
}

/// Where a run's pause stopped, in job lines.
#[derive(Debug)]
pub struct Stop {
    /// Last job line executed (wholly or partly) before the service moves.
    pub last_line: usize,
    /// First job line executed after the resume.
    pub next_line: Option<usize>,
    /// The last line was cut by the stop (resumed in the middle).
    pub mid_line: bool,
    /// Job line in progress at the request and the path position then (mm from the start).
    pub req_line: Option<usize>,
    /// Path position at the request, mm.
    pub req_path_mm: f64,
    /// Speed at the request, mm/s.
    pub v_req_mm_s: f64,
}

/// The job line (0-based) a block of sequence number `seq` came from, if any.
pub fn job_line(o: &Outcome, seq: u32) -> Option<usize> {
    if seq == u32::MAX {
        // The executive's own moves (G28's homing moves) carry no job sequence number.
        return None;
    }
    match o.run.origin_of_seq(seq) {
        Some(Origin::Job(l)) => Some(l),
        _ => None,
    }
}

/// The stop of the first pause after `t_req_us`.
pub fn stop_of(o: &Outcome, t_req_us: u64, job: &Job) -> Option<Stop> {
    let recs = &o.run.rec.records;
    let scale = sim::recorder::Scale::from_config(&job.machine);
    let first_service = recs
        .iter()
        .position(|r| r.tag.lane == Lane::Service && r.t_start_us >= t_req_us)?;
    let before = recs[..first_service]
        .iter()
        .rposition(|r| r.tag.lane == Lane::Job && job_line(o, r.tag.seq).is_some())?;
    let last = &recs[before];
    let last_line = job_line(o, last.tag.seq)?;
    let after = recs[first_service..]
        .iter()
        .find(|r| r.tag.lane == Lane::Job && job_line(o, r.tag.seq).is_some());
    let next_line = after.and_then(|r| job_line(o, r.tag.seq));
    let mid_line = after.is_some_and(|r| r.tag == last.tag || next_line == Some(last_line));
    let req = recs
        .iter()
        .position(|r| r.t_end_us >= t_req_us && r.tag.lane == Lane::Job);
    let (req_line, req_path_mm, v) = match req {
        Some(k) => {
            let r = &recs[k];
            let line = job_line(o, r.tag.seq);
            let line_start = line
                .and_then(|l| l.checked_sub(1))
                .map_or(0.0, |p| job.path_end_mm[p]);
            let done: f64 = recs[..k]
                .iter()
                .rev()
                .take_while(|x| job_line(o, x.tag.seq) == line)
                .map(|x| scale.xyz_dist_mm(&x.start, &x.end))
                .sum();
            let mut v = 0.0f64;
            for x in &recs[k.saturating_sub(2)..(k + 3).min(recs.len())] {
                let dt = (x.t_end_us.saturating_sub(x.t_start_us)) as f64 * 1e-6;
                if dt > 0.0 {
                    v = v.max(scale.xyz_dist_mm(&x.start, &x.end) / dt);
                }
            }
            (line, line_start + done, v)
        }
        None => (None, 0.0, 0.0),
    };
    Some(Stop {
        last_line,
        next_line,
        mid_line,
        req_line,
        req_path_mm,
        v_req_mm_s: v,
    })
}

/// The index of the reference layer whose end the stop is at (`None`: before the first
/// extrusion), or why it is no boundary.
pub fn boundary_of(stop: &Stop, job: &Job) -> Result<Option<usize>, String> {
    if stop.mid_line {
        return Err(format!("stopped inside line {}", stop.last_line + 1));
    }
    let before = job.layer_before(stop.last_line);
    let after = stop.next_line.and_then(|n| job.layer_after(n));
    let count = job.model.layers().len();
    match (before, after) {
        (Some(b), Some(a)) if a == b + 1 => Ok(Some(b)),
        (None, Some(0)) => Ok(None),
        (Some(b), None) if b + 1 == count => Ok(Some(b)),
        _ => Err(format!(
            "not between layers: last extrusion before in layer index {before:?}, first after in {after:?} (lines {} / {:?})",
            stop.last_line + 1,
            stop.next_line.map(|n| n + 1)
        )),
    }
}

/// Judge a `layer` pause requested at `t_req_us`: stopped at the first reachable boundary?
pub fn judge_request(o: &Outcome, t_req_us: u64, job: &Job) -> Result<(), String> {
    let stop = stop_of(o, t_req_us, job).ok_or("no pause point")?;
    let k = boundary_of(&stop, job)?;
    let accel = f64::from(job.machine.axes[0].max_accel_mm_s2);
    // Lowest allowed: the first boundary not passed at the request.
    let req_line = stop.req_line.unwrap_or(0);
    let lo = job.layer_before(req_line.saturating_sub(1));
    // Highest allowed: the first boundary whose end of extrusion is farther than braking.
    let brake_mm = stop.v_req_mm_s.powi(2) / (2.0 * accel) + REACH_MARGIN_MM;
    let count = job.model.layers().len();
    let hi = (lo.unwrap_or(0)..count).find(|&b| {
        job.last_line_of(b)
            .is_some_and(|l| job.path_end_mm[l] - stop.req_path_mm > brake_mm)
    });
    let ok_lo = match (k, lo) {
        (Some(k), Some(lo)) => k >= lo,
        (None, Some(_)) => false,
        _ => true,
    };
    let ok_hi = match (k, hi) {
        (Some(k), Some(hi)) => k <= hi,
        _ => true,
    };
    if ok_lo && ok_hi {
        Ok(())
    } else {
        let num = |k: Option<usize>| k.and_then(|k| job.model.layers().get(k)).map(|l| l.number);
        Err(format!(
            "stopped at the end of layer {:?}, allowed {:?}..={:?} (request in line {}, {:.1} mm/s, brake {brake_mm:.1} mm)",
            num(k),
            num(lo),
            num(hi),
            req_line + 1,
            stop.v_req_mm_s
        ))
    }
}

/// Judge `M761 L<n>`: stopped before the first layer numbered n, after the one before it.
pub fn judge_schedule(o: &Outcome, n: u32, job: &Job) -> Result<(), String> {
    let want = job
        .model
        .find(n)
        .ok_or_else(|| format!("the job has no layer {n}"))?;
    let stop = stop_of(o, 0, job).ok_or("never paused")?;
    let k = boundary_of(&stop, job)?;
    if k.map_or(0, |k| k + 1) == want {
        Ok(())
    } else {
        let num = |k: usize| job.model.layers().get(k).map(|l| l.number);
        Err(format!(
            "stopped before layer index {} (number {:?}), want index {want} (number {n})",
            k.map_or(0, |k| k + 1),
            num(k.map_or(0, |k| k + 1))
        ))
    }
}

/// Every place a stop at a reference layer boundary can be, as X Y Z steps: the position the
/// firmware's machine state (`cfg`) commands after each line from the last extrusion of one
/// `layerref` layer up to, not including, the first extrusion of the next layer of the same job,
/// each with the number of that next layer. For a record that has only a stop position (a
/// `sim serve` session): a stop whose X Y Z is in this list is at that boundary, judged by the
/// reference, not by the firmware's detector. The machine state gives only the positions.
pub fn boundary_positions_xyz(
    text: &str,
    comments: Comments,
    cfg: &firmware::config::MachineConfig,
) -> Vec<(u32, [i32; 3])> {
    let model = Model::of_lines(text.lines(), comments);
    let mut ranges: Vec<(usize, usize, u32)> = model
        .layers()
        .windows(2)
        .filter(|w| w[0].job == w[1].job && w[1].number > 0)
        .map(|w| (w[0].last_line, w[1].first_line, w[1].number))
        .collect();
    ranges.sort_unstable();
    let mut m = firmware::machine::MachineState::new(cfg);
    let mut out = Vec::new();
    for (i, l) in text.lines().enumerate() {
        if let Ok(line) = firmware::gcode::parse_line(l.as_bytes()) {
            if let Some(c) = &line.command {
                let _ = m.apply(c, cfg);
            }
        }
        for &(from, to, n) in &ranges {
            if (from..to).contains(&i) {
                let p = m.position_steps(cfg);
                out.push((n, [p[0], p[1], p[2]]));
            }
        }
    }
    out
}
