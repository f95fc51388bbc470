//! `sim run` exits non-zero, with the reason, when a job that should finish does not (issue 14
//! item 7): a job that stops for ever used to print "job finished" with status 0.

use std::process::Command;

fn sim_run(job: &str, args: &[&str]) -> (bool, String) {
    let dir = std::env::temp_dir().join(format!("sim-run-exit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let file = dir.join(format!("job-{}.gcode", job.len()));
    std::fs::write(&file, job).expect("write job");
    let out = Command::new(env!("CARGO_BIN_EXE_sim"))
        .arg("run")
        .arg(&file)
        .args(args)
        .output()
        .expect("run sim");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_file(&file);
    (out.status.success(), text)
}

#[test]
fn a_job_that_finishes_exits_zero() {
    let (ok, text) = sim_run("G28\nG1 X20 Y20 F3000\n", &[]);
    assert!(ok, "{text}");
    assert!(text.contains("job finished"), "{text}");
}

#[test]
fn a_job_that_never_finishes_exits_non_zero_with_the_reason() {
    // M0 parks and waits for a resume that never comes: the job cannot finish.
    let (ok, text) = sim_run("G28\nG1 X20 Y20 F3000\nM0\nG1 X40\n", &[]);
    assert!(!ok, "{text}");
    assert!(text.contains("the job did not finish"), "{text}");
    assert!(!text.contains("job finished"), "{text}");
    // JSON output too (the report is printed, the status is still a failure).
    let (ok, text) = sim_run("G28\nG1 X20 Y20 F3000\nM0\nG1 X40\n", &["--json"]);
    assert!(!ok, "{text}");
    assert!(text.contains("\"finished\": false"), "{text}");
}

#[test]
fn a_pause_that_never_completes_exits_non_zero() {
    // Staying paused (`--resume-after -1`) with a pause that parks: success. The feed hold of
    // issue 14 (`G1 X100 F7800`, `--mode now --pause-at 0.8`) must also reach Paused; until
    // the executive completes it, `sim run` says so with a failure status.
    let (ok, text) = sim_run(
        "G28\nG1 X20 Y20 F3000\nG1 X200 F3000\nG1 X20\n",
        &["--mode", "now", "--pause-at", "1.0", "--resume-after", "-1"],
    );
    assert!(ok, "{text}");
    assert!(!text.contains("never completed"), "{text}");
}

/// Issue 24: a file whose lines the printer refuses is not "a job that finished cleanly".
/// `sim run` lists them (count, the first ones with their line numbers, in the text and in
/// `--json` as `refused_lines`) and exits non-zero unless `--allow-refused`.
#[test]
fn refused_lines_are_reported_and_fail_the_run() {
    let job = "M104 S200\nM109 S200\nG28\nG1 X-500\nG1 Q5\nG1 X20 E1e9\nG1 X30 Y30 F3000\n";
    let (ok, text) = sim_run(job, &[]);
    assert!(!ok, "{text}");
    assert!(text.contains("refused lines: 3"), "{text}");
    for (n, line) in [(4, "G1 X-500"), (5, "G1 Q5"), (6, "G1 X20 E1e9")] {
        assert!(text.contains(&format!("line {n}: {line}")), "{text}");
    }
    assert!(text.contains("the printer refused 3 lines"), "{text}");
    let (ok, text) = sim_run(job, &["--json"]);
    assert!(!ok, "{text}");
    let json_end = text.rfind('}').unwrap_or(0);
    let v: serde_json::Value = serde_json::from_str(&text[..=json_end]).expect("json");
    assert_eq!(v["refused_lines"]["count"], 3, "{text}");
    assert_eq!(v["refused_lines"]["first"][0]["line"], 4, "{text}");
    assert_eq!(v["refused_lines"]["first"][1]["text"], "G1 Q5", "{text}");
    assert!(
        v["refused_lines"]["first"][2]["reply"]
            .as_str()
            .is_some_and(|r| r.starts_with("echo:refused:")),
        "{text}"
    );
    let (ok, text) = sim_run(job, &["--allow-refused"]);
    assert!(ok, "{text}");
    assert!(text.contains("refused lines: 3"), "{text}");
}

/// Every number on the command line is checked: a clear error and status 1, never a panic
/// (issue 24: `--exit-after-idle 1e308` panicked in `Duration::from_secs_f64`), and the sim
/// takes only what the firmware takes (`--segment 0.001`: the firmware's M760 L allows 0.05
/// mm at least; the run went at 480 mm/s).
#[test]
fn out_of_range_numbers_are_refused_without_a_panic() {
    let job = "G28\nG1 X20 F3000\n";
    for args in [
        &["--pause-at", "1e308"][..],
        &["--pause-at=-1"],
        &["--pause-at", "NaN"],
        &["--resume-after", "inf"],
        &["--resume-after", "NaN"],
        &["--pause-at", "1", "--resume-after", "1e300"],
        &["--baud", "0"],
        &["--baud", "4294967295"],
        &["--buffer", "0"],
        &["--buffer", "100000"],
        &["--segment", "0.001"],
        &["--segment", "0"],
        &["--segment", "1e30"],
        &["--split", "0"],
        &["--split", "inf"],
        &["--max-hours", "0"],
        &["--max-hours", "1e308"],
    ] {
        let (ok, text) = sim_run(job, args);
        assert!(!ok, "{args:?}: {text}");
        assert!(!text.contains("panicked"), "{args:?}: {text}");
        assert!(text.contains("sim: --"), "{args:?}: {text}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_sim"))
        .args(["serve", "--exit-after-idle", "1e308"])
        .output()
        .expect("sim serve");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("--exit-after-idle"), "{err}");
}

/// No run goes faster than the physics allows: `G1 X100 F7800` (130 mm/s) at 500 mm/s² takes
/// at least 100/130 + 130/500 = 1.029 s, at the shortest segment the sim accepts too.
#[test]
fn the_shortest_segment_keeps_feed_and_acceleration() {
    for seg in ["0.05", "0.2"] {
        let (ok, text) = sim_run(
            "G92 X0 Y0 Z0\nG1 X100 F7800\n",
            &["--segment", seg, "--json"],
        );
        assert!(ok, "{text}");
        let v: serde_json::Value = serde_json::from_str(&text).expect("json");
        // From the first byte: the move and the two lines' wire time.
        let t = v["print_time_s"].as_f64().unwrap_or(0.0);
        assert!(t >= 1.029, "--segment {seg}: the move took {t:.3} s");
        assert!(t < 1.1, "--segment {seg}: the move took {t:.3} s");
    }
}

/// The input is streamed: a 1 GiB file (sparse, no line end: one line of zeros) runs with
/// 512 MiB of address space (issue 24: a 2 GB file aborted with a 2 GB allocation).
#[test]
fn a_file_larger_than_memory_is_streamed() {
    let dir = std::env::temp_dir().join(format!("sim-run-huge-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let file = dir.join("huge.gcode");
    let f = std::fs::File::create(&file).expect("create");
    f.set_len(1 << 30).expect("sparse file");
    drop(f);
    let out = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit -v 524288; exec '{}' run '{}' --json --allow-refused",
            env!("CARGO_BIN_EXE_sim"),
            file.display()
        ))
        .output()
        .expect("run sim");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
    assert!(!text.contains("memory allocation"), "{text}");
    assert!(out.status.success(), "{text}");
    assert!(text.contains("\"cut_lines\": 1"), "{text}");
}
