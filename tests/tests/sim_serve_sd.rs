//! `sim serve --sd DIR`: a host lists the card, selects a sliced file in a sub-directory by its
//! long path, starts it (M24), asks for a layer pause (M25) while it prints, resumes (M24) and
//! sees `Done printing file`. The session's record (recorded from the executed steps, independent of the
//! firmware's layer detector) must show the stop at the first layer boundary after the
//! request, nothing lost or duplicated, the resume exact; and the stop position must be one
//! where the file itself has a layer marker (found here by reading the file with a tracker of
//! its own).

use firmware::config::MachineConfig;
use sim::run::Policy;
use sim::serve::ServeArgs;
use std::time::Duration;
use tests::gcode::layer_markers;
use tests::pty::serve_in_thread;

const FIXTURE: &str = "prusa-zhop.gcode";

/// How long the host waits for an `ok`.
const OK_WAIT: Duration = Duration::from_secs(30);

#[test]
fn a_host_prints_a_sliced_file_from_the_card_with_a_layer_pause() {
    let src = format!("{}/fixtures/corpus/{FIXTURE}", env!("CARGO_MANIFEST_DIR"));
    let gcode = std::fs::read_to_string(&src).expect("fixture");
    let dir = std::env::temp_dir().join(format!("sim-serve-sd-{}", std::process::id()));
    // In a sub-directory: M20 lists it by its path, M23 opens it by its path.
    std::fs::create_dir_all(dir.join("prints")).unwrap();
    std::fs::write(dir.join("prints").join(FIXTURE), &gcode).unwrap();

    let sd = dir.clone();
    let (server, mut host) = serve_in_thread(
        ServeArgs {
            speed: 50.0,
            record: None,
            policy: Policy::Firmware,
            exit_after_idle: 1.0,
            link: None,
            flash: None,
            sd: Some(sd),
            tft: false,
            tft_control_bytes: false,
            host_paced: false,
            machine: None,
            trace: None,
            allow_cold_extrusion: false,
        },
        Duration::from_secs(20),
    );

    host.write("M115");
    host.until("Cap:SDCARD:1", Duration::from_secs(30), |l| {
        l == "Cap:SDCARD:1"
    });
    host.ok(OK_WAIT);
    host.write("M20 L");
    host.until("the file in the list", Duration::from_secs(30), |l| {
        l.ends_with(&format!(" {} prints/{FIXTURE}", gcode.len()))
    });
    host.until("End file list", Duration::from_secs(30), |l| {
        l == "End file list"
    });
    host.ok(OK_WAIT);
    host.write(&format!("M23 prints/{FIXTURE}"));
    let opened = host.until("File opened", Duration::from_secs(30), |l| {
        l.starts_with("File opened: ")
    });
    assert!(
        opened.ends_with(&format!("Size: {}", gcode.len())),
        "{opened}"
    );
    host.until("File selected", Duration::from_secs(30), |l| {
        l == "File selected"
    });
    host.ok(OK_WAIT);
    host.write("M27 S1");
    host.ok(OK_WAIT);
    host.write("M24");
    host.ok(OK_WAIT);
    // Ask for the layer pause once a third of the file has been read.
    loop {
        let l = host.until("SD progress", Duration::from_secs(120), |l| {
            l.starts_with("SD printing byte ")
        });
        let (a, b) = l["SD printing byte ".len()..].split_once('/').unwrap();
        let (a, b): (u64, u64) = (a.parse().unwrap(), b.parse().unwrap());
        assert_eq!(b, gcode.len() as u64);
        if a > b / 3 {
            break;
        }
    }
    host.write("M25");
    host.until("//action:paused", Duration::from_secs(120), |l| {
        l.contains("//action:paused")
    });
    host.write("M27");
    host.until("M27 while paused", Duration::from_secs(30), |l| {
        l.starts_with("SD printing byte ")
    });
    host.write("M24");
    host.until("Done printing file", Duration::from_secs(300), |l| {
        l == "Done printing file"
    });
    drop(host);

    let record = server.record().expect("serve session");
    let _ = std::fs::remove_dir_all(&dir);
    let s = &record.session;
    assert!(s.finished && !s.cancelled, "{s:#?}");
    assert_eq!(s.lost_moves + s.duplicated_moves, 0, "{s:#?}");
    assert_eq!(s.layers_extruded, 10, "{s:#?}");
    let reports = record.pauses;
    assert_eq!(reports.len(), 1, "{reports:#?}");
    let r = &reports[0];
    assert_eq!(r.mode, "layer");
    assert!(r.stopped_at_layer_boundary, "{r:#?}");
    assert_eq!(r.resume_position_error_steps, Some(0), "{r:#?}");
    assert_eq!(r.lost_moves + r.duplicated_moves, 0, "{r:#?}");
    // The stop is where the file has a layer marker (to the step).
    let stop = r.pause_point_steps.expect("pause point");
    let cfg = MachineConfig::ENDER3;
    // Where the head is at each of the file's markers (a tracker of the test's own).
    let markers: Vec<([f64; 3], f64)> = layer_markers(&gcode, ";LAYER_CHANGE")
        .iter()
        .map(|m| (m.pos_mm, m.fed_mm))
        .collect();
    assert_eq!(markers.len(), 10);
    let k = markers
        .iter()
        .position(|(m, _)| {
            (0..3).all(|i| {
                let want = (m[i] * f64::from(cfg.axes[i].steps_per_mm)).round() as i64;
                (i64::from(stop[i]) - want).abs() <= 1
            })
        })
        .filter(|&k| k > 0)
        .unwrap_or_else(|| panic!("stop {stop:?} is at no layer marker of the file: {markers:?}"));
    // And it is the first marker after the request: the session record says so from the
    // extrusion heights; when the request came in a layer change (after the file's marker,
    // before the new layer's first extrusion) the heights cannot tell, and the filament fed
    // from the request to the stop shows it: no more than the file feeds between the two
    // markers around the stop (a late stop would add the rest of the layer before).
    let layer_e = markers[k].1 - markers[k - 1].1;
    let fed = r
        .extrusion_after_request_mm
        .expect("extrusion after the request");
    assert!(
        r.first_boundary_after_request || fed <= layer_e + 0.05,
        "stop at marker {k}: fed {fed} mm after the request, the layer feeds {layer_e} mm: {r:#?}"
    );
}

/// Issue 24: `sim serve --sd broken.img` (a boot sector with 0 sectors per cluster) died at
/// start with a division by zero inside embedded-sdmmc. Now it serves: the card is refused
/// with its reason, M23 answers `No media`, and the printer moves.
#[test]
fn a_broken_card_image_is_refused_and_the_printer_serves() {
    let dir = std::env::temp_dir().join(format!("sim-serve-sd-broken-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let img = dir.join("broken.img");
    sim::sd::write_image(&img, &[("A.GCO".into(), b"G28\n".to_vec())]).expect("card image");
    let mut card = std::fs::read(&img).expect("image");
    // The partition's boot sector: BPB_SecPerClus (byte 13) := 0.
    card[sim::sd::PARTITION_START_BLOCK as usize * 512 + 13] = 0;
    std::fs::write(&img, &card).expect("write");
    let (server, mut host) = serve_in_thread(
        ServeArgs {
            speed: 20.0,
            record: None,
            policy: Policy::Firmware,
            exit_after_idle: 1.0,
            link: None,
            flash: None,
            sd: Some(img),
            tft: false,
            tft_control_bytes: false,
            host_paced: false,
            machine: None,
            trace: None,
            allow_cold_extrusion: false,
        },
        Duration::from_secs(20),
    );
    host.write("M21");
    host.until("SD init fail", OK_WAIT, |l| {
        l == "echo:SD init fail (no FAT volume: Invalid number of blocks per cluster)"
    });
    host.ok(OK_WAIT);
    host.write("M23 A.GCO");
    host.until("No media", OK_WAIT, |l| l.contains("No media"));
    host.ok(OK_WAIT);
    host.write("G28");
    host.ok(OK_WAIT);
    host.write("G1 X10 F3000");
    host.ok(OK_WAIT);
    host.write("M400");
    host.ok(OK_WAIT);
    host.write("M114");
    host.until("the position", OK_WAIT, |l| l.starts_with("X:10.00"));
    drop(host);
    let record = server.record().expect("serve session");
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(record.session.lost_moves, 0, "{:#?}", record.session);
}
