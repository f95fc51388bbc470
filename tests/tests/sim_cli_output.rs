//! `sim`'s output paths never panic and never destroy what a path points to: a closed pipe or a
//! full disk on standard output is a clean error with exit status 1; `sim serve --link` refuses
//! an existing file (and a link to anything but a pseudo-terminal) and leaves it intact.
//! About 1 s.

mod hosts_common;

use hosts_common::bin;
use std::io::Write;
use std::process::{Command, Stdio};

/// `sim pattern demo` and `sim run` of a small job with standard output closed before they
/// write (as `| head -0` would): exit 1, an error message, no panic.
#[test]
fn a_closed_pipe_is_a_clean_error() {
    let sim = bin("sim", "sim");
    let job = std::env::temp_dir().join(format!("sim_cli_job_{}.gcode", std::process::id()));
    let mut f = std::fs::File::create(&job).expect("job file");
    writeln!(
        f,
        "G90\nM83\nG92 X10 Y10 Z0.2 E0\nG1 X20 E1 F1800\nG1 Y20 E1"
    )
    .expect("write");
    drop(f);
    for args in [
        vec!["pattern".to_string(), "demo".into()],
        vec!["run".to_string(), job.display().to_string()],
    ] {
        // The pipe's reader is gone before the child starts, so its first write fails
        // (closing it after the spawn raced with a child that wrote everything first).
        let (reader, writer) = std::io::pipe().expect("pipe");
        drop(reader);
        let out = Command::new(&sim)
            .args(&args)
            .stdout(writer)
            .stderr(Stdio::piped())
            .output()
            .expect("sim output");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("writing to standard output"),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    let _ = std::fs::remove_file(&job);
}

#[test]
fn a_full_disk_is_a_clean_error() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        return; // no /dev/full here: nothing to check
    };
    let out = Command::new(bin("sim", "sim"))
        .args(["pattern", "demo"])
        .stdout(full)
        .stderr(Stdio::piped())
        .output()
        .expect("sim");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("writing to standard output"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn serve_link_never_replaces_an_existing_file() {
    let dir = std::env::temp_dir().join(format!("sim_cli_link_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let file = dir.join("printer.txt");
    std::fs::write(&file, "precious").expect("file");
    let other = dir.join("other");
    std::os::unix::fs::symlink(&file, &other).expect("symlink");
    for l in [&file, &other] {
        let out = Command::new(bin("sim", "sim"))
            .args(["serve", "--exit-after-idle", "0.2", "--link"])
            .arg(l)
            .output()
            .expect("sim serve");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("refusing to replace"), "{err}");
    }
    assert_eq!(std::fs::read_to_string(&file).expect("file"), "precious");
    assert_eq!(std::fs::read_link(&other).expect("link"), file);
    // A stale link to a pseudo-terminal is replaced, and removed when the session ends.
    let stale = dir.join("stale");
    std::os::unix::fs::symlink("/dev/pts/999999", &stale).expect("symlink");
    let out = Command::new(bin("sim", "sim"))
        .args(["serve", "--exit-after-idle", "0.2", "--link"])
        .arg(&stale)
        .output()
        .expect("sim serve");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        std::fs::symlink_metadata(&stale).is_err(),
        "link left behind"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
