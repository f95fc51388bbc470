//! Every subcommand meets bad input, full disks, closed pipes and odd output paths with a
//! clear error and a non-zero exit — never a panic, an abort, a hang, an unbounded allocation
//! or a destroyed file (issue 15, "Crashes and data loss").

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-tools"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ht-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn run(args: &[&str]) -> Output {
    bin()
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run host-tools")
}

/// The command failed with a message (exit status 1 or 2, not a signal or a panic's 101).
fn assert_clean_error(o: &Output, want: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        matches!(o.status.code(), Some(1 | 2)),
        "status {:?}, stderr: {err}",
        o.status
    );
    assert!(!err.contains("panicked"), "panic: {err}");
    assert!(err.contains(want), "expected `{want}` in: {err}");
}

const SCRIPT: &str = "let t = init(1.75, 200, 0, 0.2, 100, 100, 0.2);\nt.forward(20, 0);\nt\n";

fn script(dir: &Path) -> PathBuf {
    let p = dir.join("line.rhai");
    std::fs::write(&p, SCRIPT).expect("script");
    p
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

#[test]
fn numeric_options_beyond_their_limits_are_refused() {
    let d = tmp("limits");
    let out = d.join("o.gcode");
    for args in [
        &["grow", "--boundary", "circle", "--size", "1e308"][..],
        &["grow", "--boundary", "circle", "--layer-height", "1e-9"],
        &["grow", "--boundary", "circle", "--layer-height", "1e9"],
        &["grow", "--boundary", "circle", "--line-width", "1e-9"],
        &["grow", "--boundary", "circle", "--layers", "4000000000"],
        &[
            "additive",
            "--base",
            "b.stl",
            "--shape",
            "s.stl",
            "--face",
            "0",
            "--walls",
            "4294967295",
        ],
        &[
            "additive",
            "--base",
            "b.stl",
            "--shape",
            "s.stl",
            "--face",
            "0",
            "--layer-height",
            "1e-9",
        ],
        &[
            "additive",
            "--base",
            "b.stl",
            "--shape",
            "s.stl",
            "--face",
            "0",
            "--line-width",
            "1e-9",
        ],
        &[
            "additive", "--base", "b.stl", "--shape", "s.stl", "--face", "0", "--offset", "1e308,0",
        ],
        &["compile", "x.rhai", "--max-operations", "0"],
        &["compile", "x.rhai", "--max-memory-mib", "0"],
        &["compile", "x.rhai", "--max-memory-mib", "1000000"],
        &["timebased", "x.gcode", "--period-ms", "1e308"],
        &["timebased", "x.gcode", "--period-ms", "0"],
        &["timebased", "x.gcode", "--period-ms", "-5"],
        &["timebased", "x.gcode", "--period-ms", "nan"],
        &["timebased", "x.gcode", "--period-ms", "0.001"],
        &["timebased", "x.gcode", "--period-ms", "60001"],
        &[
            "cure-check",
            "x.gcode",
            "--cure",
            "5",
            "--period-ms",
            "1e308",
        ],
    ] {
        let mut a = args.to_vec();
        a.extend(["-o", s(&out)]);
        let o = run(&a);
        assert_clean_error(&o, "error");
        assert!(!out.exists(), "{args:?} wrote output");
    }
}

fn ascii_stl(path: &Path, scale: f32) {
    let mut t = String::from("solid t\n");
    let tri = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| {
        format!(
            "facet normal 0 0 1\nouter loop\nvertex {} {} {}\nvertex {} {} {}\nvertex {} {} {}\nendloop\nendfacet\n",
            a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]
        )
    };
    t += &tri([0.0, 0.0, 0.0], [scale, 0.0, 0.0], [0.0, scale, 0.0]);
    t += &tri([0.0, 0.0, 0.0], [0.0, scale, 0.0], [0.0, 0.0, scale]);
    t += "endsolid t\n";
    std::fs::write(path, t).expect("stl");
}

#[test]
fn stl_with_huge_coordinates_is_refused() {
    let d = tmp("stl");
    let (b, sh) = (d.join("b.stl"), d.join("s.stl"));
    ascii_stl(&b, 1e38);
    ascii_stl(&sh, 5.0);
    let o = run(&[
        "additive",
        "--base",
        s(&b),
        "--shape",
        s(&sh),
        "--face",
        "0",
        "-o",
        s(&d.join("o.gcode")),
    ]);
    assert_clean_error(&o, "beyond");
}

#[test]
fn endless_inputs_stop_at_their_size_limit() {
    let d = tmp("zero");
    let o = run(&["compile", "/dev/zero", "-o", s(&d.join("o.gcode"))]);
    assert_clean_error(&o, "longer than");
    let o = run(&[
        "compile",
        s(&script(&d)),
        "--printer",
        "/dev/zero",
        "-o",
        s(&d.join("o.gcode")),
    ]);
    assert_clean_error(&o, "longer than");
    let o = run(&[
        "grow",
        "--boundary",
        "/dev/zero",
        "-o",
        s(&d.join("o.gcode")),
    ]);
    assert_clean_error(&o, "longer than");
}

#[test]
fn full_disk_is_an_error_for_every_writer() {
    let d = tmp("full");
    let sc = script(&d);
    let g = d.join("g.gcode");
    let o = run(&["compile", s(&sc), "-o", s(&g)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for args in [
        &["compile", s(&sc), "-o", "/dev/full"][..],
        &["timebased", s(&g), "-o", "/dev/full"],
        &[
            "grow",
            "--boundary",
            "circle",
            "--size",
            "20",
            "--nodes",
            "300",
            "--quiet",
            "-o",
            "/dev/full",
        ],
    ] {
        assert_clean_error(&run(args), "/dev/full");
    }
    // preview picks the format from the name: a link named .svg to the full device.
    let link = d.join("p.svg");
    std::os::unix::fs::symlink("/dev/full", &link).expect("symlink");
    assert_clean_error(&run(&["preview", s(&g), "-o", s(&link)]), "p.svg");
}

#[test]
fn closed_stdout_is_an_error_not_a_panic() {
    let d = tmp("pipe");
    let sc = script(&d);
    let g = d.join("g.gcode");
    for args in [
        vec![
            "compile".to_string(),
            s(&sc).into(),
            "-o".into(),
            s(&g).into(),
        ],
        vec![
            "timebased".into(),
            s(&g).into(),
            "-o".into(),
            s(&d.join("t.gcode")).into(),
        ],
        vec![
            "preview".into(),
            s(&g).into(),
            "-o".into(),
            s(&d.join("p.svg")).into(),
        ],
        vec![
            "grow".into(),
            "--boundary".into(),
            "circle".into(),
            "--size".into(),
            "20".into(),
            "--nodes".into(),
            "300".into(),
            "--quiet".into(),
            "-o".into(),
            s(&d.join("w.gcode")).into(),
        ],
    ] {
        let (reader, writer) = std::io::pipe().expect("pipe");
        drop(reader);
        let o = bin()
            .args(&args)
            .stdin(Stdio::null())
            .stdout(writer)
            .stderr(Stdio::piped())
            .output()
            .expect("run");
        assert_clean_error(&o, "standard output");
    }
}

#[test]
fn output_paths_keep_links_devices_and_directories() {
    let d = tmp("paths");
    let sc = script(&d);
    // A link: the file it points to gets the G-code, the link stays a link.
    let real = d.join("real.gcode");
    std::fs::write(&real, "old").expect("write");
    let link = d.join("link.gcode");
    std::os::unix::fs::symlink(&real, &link).expect("symlink");
    let o = run(&["compile", s(&sc), "-o", s(&link)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::symlink_metadata(&link)
        .expect("meta")
        .file_type()
        .is_symlink());
    assert!(std::fs::read_to_string(&real)
        .expect("read")
        .contains("G1 X120"));
    // A device is written through, not replaced.
    let o = run(&["compile", s(&sc), "-o", "/dev/null"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // A directory is refused, and nothing is left next to it.
    let sub = d.join("out");
    std::fs::create_dir(&sub).expect("mkdir");
    assert_clean_error(&run(&["compile", s(&sc), "-o", s(&sub)]), "is a directory");
    let mut names: Vec<String> = std::fs::read_dir(&d)
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["line.rhai", "link.gcode", "out", "real.gcode"]);
}

/// A script that grows without end (doubling a string or an array every operation, or one
/// `pad` to a huge size) stops with a clean error: the sandbox bounds the heap as a whole
/// (issue 23 took Rhai's per-value limits out: they made appending to a path quadratic).
#[test]
fn runaway_scripts_stop_at_the_memory_budget() {
    let d = tmp("memory");
    let out = d.join("o.gcode");
    for (name, src) in [
        ("string", "let s = \"xy\"; loop { s += s; }"),
        ("array", "let a = [1, 2]; loop { a += a; }"),
        ("nested", "let a = [1]; loop { a.push(a); }"),
        (
            "pad",
            "let a = []; a.pad(1000000000000, 0); turtle(0, 0, 0)",
        ),
        ("blob", "let b = blob(1000000000000); turtle(0, 0, 0)"),
    ] {
        let script = d.join(format!("{name}.rhai"));
        std::fs::write(&script, src).expect("script");
        let o = run(&[
            "compile",
            s(&script),
            "-o",
            s(&out),
            "--max-memory-mib",
            "64",
        ]);
        assert_clean_error(&o, "error");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("memory") || err.contains("sandbox"),
            "{name}: {err}"
        );
        assert!(!out.exists(), "{name} wrote output");
    }
}

/// An output path that names an input — the same path, a symbolic link or a hard link to it —
/// is refused before anything is written, and the input stays as it was (before, `compile
/// d.rhai -o d.rhai` replaced the design with its G-code, and `timebased` its source).
#[test]
fn an_output_that_is_an_input_is_refused() {
    let d = tmp("same");
    let design = script(&d);
    let gcode = d.join("job.gcode");
    let o = run(&["compile", s(&design), "-o", s(&gcode)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (design_text, gcode_text) = (
        std::fs::read(&design).expect("design"),
        std::fs::read(&gcode).expect("gcode"),
    );
    std::os::unix::fs::symlink(&gcode, d.join("link.gcode")).expect("symlink");
    std::fs::hard_link(&gcode, d.join("hard.gcode")).expect("hard link");
    let (link, hard) = (d.join("link.gcode"), d.join("hard.gcode"));
    let stl = d.join("cube.stl");
    ascii_stl(&stl, 10.0);
    let cases: Vec<Vec<&str>> = vec![
        vec!["compile", s(&design), "-o", s(&design)],
        vec!["timebased", s(&gcode), "-o", s(&gcode)],
        vec!["timebased", s(&gcode), "-o", s(&link)],
        vec!["timebased", s(&link), "-o", s(&hard)],
        vec![
            "cure-check",
            s(&gcode),
            "--cure",
            "5",
            "--heatmap",
            s(&hard),
        ],
        vec!["preview", s(&gcode), "--html", "-o", s(&gcode)],
        vec![
            "additive",
            "--base",
            s(&stl),
            "--shape",
            s(&stl),
            "--face",
            "0",
            "-o",
            s(&stl),
        ],
    ];
    for args in cases {
        let o = run(&args);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(
            !String::from_utf8_lossy(&o.stderr).contains("panicked"),
            "{args:?}"
        );
        assert_eq!(
            std::fs::read(&design).expect("design"),
            design_text,
            "{args:?}"
        );
        assert_eq!(
            std::fs::read(&gcode).expect("gcode"),
            gcode_text,
            "{args:?}"
        );
    }
    let o = run(&["timebased", s(&gcode), "-o", s(&hard)]);
    assert_clean_error(&o, "that is the input");
    let o = run(&["compile", s(&design), "-o", s(&design)]);
    assert_clean_error(&o, "that is the input");
    let _ = std::fs::remove_dir_all(&d);
}
