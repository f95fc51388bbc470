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
