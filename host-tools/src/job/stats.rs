//! Statistics of a G-code job: layers (or turns), moves, an acceleration-aware print time
//! (the [`crate::design::motion`] model with the profile's limits), filament length/volume/mass,
//! bounding box of the printed material and time per layer.
//!
//! Layers are the firmware's ([`firmware::layer::LayerDetector`] through the reader): the
//! slicer's markers (`;LAYER_CHANGE`, `; CHANGE_LAYER`, `;LAYER:n`, `; layer n`, `M73 L`,
//! Klipper's `CURRENT_LAYER`; our writer emits one `;LAYER_CHANGE` per helix turn), or in a
//! file without any, the heights of the extruding moves and, in a spiral vase, its turns
//! found from the path — the same boundaries the printer's layer pause stops at, numbered as
//! the printer numbers them (from 1, as the slicers' previews do).

use crate::design::motion::{
    plan_marks, prelude_marks, LayerMark, MotionLimits, MoveKind, PrintHeights, Segment,
};
use crate::design::profile::Profile;
use crate::gcode::read::{default_reader, BadLines, ReadError};
use serde::Serialize;

/// Bounding box in JSON form.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BBoxMm {
    /// Lowest X, Y, Z, mm.
    pub min: [f64; 3],
    /// Highest X, Y, Z, mm.
    pub max: [f64; 3],
}

/// Time spent in one layer.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LayerTime {
    /// The firmware's layer number — what `M761 L<n>` and the printer's layer pause call this
    /// layer: the n-th layer printed, from 1 (the slicers' preview numbers; Cura's
    /// `;LAYER:n` is layer n + 1).
    pub layer: u32,
    /// The height the layer prints at — where its first extruding move starts, never a
    /// travel's lift — else the marker's, mm.
    pub z_mm: Option<f64>,
    /// Time from this layer's start to the next one's, s.
    pub time_s: f64,
}

/// Statistics of one job.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stats {
    /// Layers (or turns of a layer-free print).
    pub layers: u32,
    /// Where the layers came from: "markers" or "z".
    pub layer_source: &'static str,
    /// Moves (arcs count per chord).
    pub moves: u64,
    /// Extruding moves.
    pub print_moves: u64,
    /// Moves without extrusion.
    pub travel_moves: u64,
    /// Extruder-only moves (retract/prime).
    pub extruder_moves: u64,
    /// Estimated print time, s.
    pub print_time_s: f64,
    /// Net filament pushed, mm.
    pub filament_mm: f64,
    /// Filament volume, mm³.
    pub filament_volume_mm3: f64,
    /// Filament mass, g.
    pub filament_mass_g: f64,
    /// Bounding box of extruding moves (all moves if nothing extrudes), mm.
    pub bbox_mm: BBoxMm,
    /// Path length of extruding moves, mm.
    pub print_path_mm: f64,
    /// Path length of travels, mm.
    pub travel_path_mm: f64,
    /// Lines read.
    pub lines: u64,
    /// Bytes read.
    pub bytes: u64,
    /// Time before the first layer mark (start code moves), s.
    pub before_first_layer_s: f64,
    /// Time per layer, in file order.
    pub layer_times: Vec<LayerTime>,
    /// Lines the firmware would reject: skipped (the printer answers `Error:` and does
    /// nothing), counted here.
    pub bad_lines: u64,
    /// The first of those lines with their errors.
    pub bad_line_errors: Vec<ReadError>,
}

/// Computes statistics of `input` for `profile`. Lines the firmware's parser rejects are
/// skipped and reported in [`Stats::bad_lines`] (a bad line does not hide the whole file).
pub fn stats(input: &[u8], profile: &Profile) -> Result<Stats, ReadError> {
    let limits = MotionLimits::from_profile(profile);
    let mut print_moves = 0u64;
    let mut travel_moves = 0u64;
    let mut extruder_moves = 0u64;
    let mut net_e = 0.0f64;
    let mut print_path = 0.0;
    let mut travel_path = 0.0;
    let mut bb_print = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let mut bb_all = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    // Time per layer by markers (index = marker layer).
    let mut marker_time: Vec<f64> = vec![0.0];
    // Plain comparisons: `f64::min`/`max` handle NaN (never present here) at a cost that
    // showed in profiles of large files.
    let grow = |bb: &mut ([f64; 3], [f64; 3]), p: &[f64; 4]| {
        for (k, v) in p.iter().take(3).enumerate() {
            if *v < bb.0[k] {
                bb.0[k] = *v;
            }
            if *v > bb.1[k] {
                bb.1[k] = *v;
            }
        }
    };
    let mut heights = PrintHeights::default();
    let mut seg_sink = |s: Segment| {
        heights.note(&s);
        let d = s.duration_s();
        net_e += s.end[3] - s.start[3];
        grow(&mut bb_all, &s.end);
        match s.kind {
            MoveKind::Print => {
                print_moves += 1;
                print_path += s.len_mm;
                grow(&mut bb_print, &s.start);
                grow(&mut bb_print, &s.end);
            }
            MoveKind::Travel => {
                travel_moves += 1;
                travel_path += s.len_mm;
            }
            MoveKind::Extruder => extruder_moves += 1,
        }
        let li = s.layer as usize;
        if li >= marker_time.len() {
            marker_time.resize(li + 1, 0.0);
        }
        marker_time[li] += d;
    };
    // The firmware's marks, in order (mark k starts segment layer k+1).
    let mut marks: Vec<LayerMark> = Vec::new();
    let mut reader = default_reader();
    reader.bad_line_policy = BadLines::Skip;
    let totals = plan_marks(&mut reader, input, limits, &mut seg_sink, &mut |m| {
        marks.push(m)
    })?;
    if marker_time.len() <= marks.len() {
        marker_time.resize(marks.len() + 1, 0.0);
    }
    // What prints before the first layer is no layer (docs/planner.md, "What a layer is"):
    // the firmware's detector numbers Z rises from 1 before it knows the file's markers (a
    // purge line; the i3 Mega's two at Z 0.3 and 0.2), then starts again at 1 with the first
    // marker or the first layer proper — the number its layer pause and `M761 L<n>` use. The
    // marks before that restart are the prelude: their time is the time before the first layer.
    let prelude = prelude_marks(&marks);
    let mut heights_of: Vec<Option<f64>> = (0..marks.len())
        .map(|k| heights.get(k as u32 + 1).or(marks[k].z_mm))
        .collect();
    if prelude > 0 {
        let t: f64 = marker_time.drain(1..=prelude).sum();
        marker_time[0] += t;
        marks.drain(..prelude);
        heights_of.drain(..prelude);
    }
    let n = marks.len();
    let before_first_layer_s = marker_time.first().copied().unwrap_or(0.0);
    let layer_times = marks
        .iter()
        .zip(&heights_of)
        .zip(marker_time.iter().skip(1))
        .map(|((m, z), t)| LayerTime {
            layer: m.number,
            z_mm: *z,
            time_s: *t,
        })
        .collect();
    let source = if totals.explicit_layers {
        "markers"
    } else {
        "z"
    };
    let bb = if print_moves > 0 { bb_print } else { bb_all };
    let bbox_mm = if bb.0[0].is_finite() {
        BBoxMm {
            min: bb.0,
            max: bb.1,
        }
    } else {
        BBoxMm {
            min: [0.0; 3],
            max: [0.0; 3],
        }
    };
    let filament_mm = net_e.max(0.0);
    let vol = filament_mm * profile.filament_area_mm2();
    Ok(Stats {
        layers: n as u32,
        layer_source: source,
        moves: totals.moves,
        print_moves,
        travel_moves,
        extruder_moves,
        print_time_s: totals.time_s,
        filament_mm,
        filament_volume_mm3: vol,
        filament_mass_g: vol * profile.filament_density_g_cm3 / 1000.0,
        bbox_mm,
        print_path_mm: print_path,
        travel_path_mm: travel_path,
        lines: totals.lines,
        bytes: input.len() as u64,
        before_first_layer_s,
        layer_times,
        bad_lines: totals.bad_lines,
        bad_line_errors: reader.bad_lines,
    })
}

/// `h:mm:ss` for a duration in seconds.
pub fn hms(s: f64) -> String {
    let t = s.max(0.0).round() as u64;
    format!("{}:{:02}:{:02}", t / 3600, (t / 60) % 60, t % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_layers_time_and_filament() {
        let g = b"G90\nM82\nG92 E0\n;LAYER_CHANGE\n;Z:0.2\nG0 X0 Y0 Z0.2 F6000\nG1 X100 E5 F3000\n\
                  ;LAYER_CHANGE\n;Z:0.4\nG1 Z0.4\nG1 X0 E10\n";
        let s = stats(g, &Profile::ender3()).expect("stats");
        assert_eq!(s.layers, 2);
        assert_eq!(s.layer_source, "markers");
        assert!((s.filament_mm - 10.0).abs() < 1e-9);
        assert_eq!(s.bbox_mm.max[0], 100.0);
        assert!(
            s.print_time_s > 4.0 && s.print_time_s < 6.0,
            "{}",
            s.print_time_s
        );
        assert_eq!(s.layer_times.len(), 2);
        assert_eq!(s.layer_times[1].z_mm, Some(0.4));
        // The firmware's numbers: PrusaSlicer markers counted from 1.
        assert_eq!(s.layer_times[0].layer, 1);
        assert_eq!(s.layer_times[1].layer, 2);
        let sum: f64 = s.layer_times.iter().map(|l| l.time_s).sum();
        assert!((sum + s.before_first_layer_s - s.print_time_s).abs() < 1e-9);
    }

    /// Cura's `;LAYER:0` is layer 1 (after a purge line that the `;FLAVOR` header keeps from
    /// being a layer).
    #[test]
    fn cura_numbers_are_the_firmwares() {
        let g =
            b";FLAVOR:Marlin\n;LAYER_COUNT:2\nG92 E0\nG1 Z0.3 F600\nG1 X0 Y100 E5 F1500\nG92 E0\n\
                  ;LAYER:0\nG0 X10 Y10 Z0.2\nG1 X20 E1\n;LAYER:1\nG0 Z0.4\nG1 X10 E2\n";
        let s = stats(g, &Profile::ender3()).expect("stats");
        assert_eq!(s.layers, 2);
        let nums: Vec<u32> = s.layer_times.iter().map(|l| l.layer).collect();
        assert_eq!(nums, [1, 2]);
        assert!(s.before_first_layer_s > 0.0);
    }

    /// Without comments, Cura's Ender-3 purge line (at Z 0.28, above the 0.2 mm first layer)
    /// is no layer: the count is the slicer's, its time is before the first layer.
    #[test]
    fn a_purge_line_above_the_first_layer_is_no_layer() {
        let g =
            b"G28\nG92 E0\nG1 Z2 F3000\nG1 X0.1 Y20 Z0.28 F5000\nG1 X0.1 Y200 Z0.28 E15 F1500\n\
                  G92 E0\nG1 Z2\nG0 X10 Y10 Z0.2\nG1 X20 E1\nG0 Z0.4\nG1 X10 E2\n";
        let s = stats(g, &Profile::ender3()).expect("stats");
        assert_eq!(s.layers, 2);
        let nums: Vec<u32> = s.layer_times.iter().map(|l| l.layer).collect();
        assert_eq!(nums, [1, 2]);
        assert!(s.before_first_layer_s > 1.0, "{}", s.before_first_layer_s);
    }

    #[test]
    fn z_layers_without_markers() {
        let g = b"G1 Z0.2 F600\nG1 X10 E1 F1200\nG1 Z0.4\nG1 X0 E2\nG1 Z0.6\nG1 X10 E3\n";
        let s = stats(g, &Profile::ender3()).expect("stats");
        assert_eq!(s.layer_source, "z");
        assert_eq!(s.layers, 3);
    }

    /// A bad line in the middle is skipped with its error; the rest of the file counts.
    #[test]
    fn bad_line_is_skipped_and_reported() {
        let g = b"G90\nM82\nG1 X10 E1 F1200\nG1 X1e99 Y?\nG1 X20 E2\nN5 G1 X30 E3*99\nG1 X40 E4\n";
        let s = stats(g, &Profile::ender3()).expect("stats reads past bad lines");
        assert_eq!(s.bad_lines, 2);
        assert_eq!(
            s.bad_line_errors.iter().map(|e| e.line).collect::<Vec<_>>(),
            [4, 6]
        );
        assert_eq!(s.bbox_mm.max[0], 40.0);
        assert!((s.filament_mm - 4.0).abs() < 1e-9);
        // The strict reader the writers use still refuses.
        let strict = crate::design::motion::plan_gcode(
            g,
            MotionLimits::from_profile(&Profile::ender3()),
            &mut |_| {},
            &mut |_, _, _| {},
        );
        assert_eq!(strict.map_err(|e| e.line), Err(4));
    }
}
