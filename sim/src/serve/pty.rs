//! The session's terminal: the pseudo-terminal the host opens, the `--link` symlink check,
//! and the signals that end the session.

use anyhow::Context;
use nix::fcntl::{fcntl, FcntlArg, OFlag};
use nix::sys::termios;
use std::os::fd::OwnedFd;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

pub(super) static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: nix::libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

pub(super) fn install_signals() {
    use nix::sys::signal::{sigaction, SaFlags, SigAction, SigHandler, SigSet, Signal};
    let sa = SigAction::new(
        SigHandler::Handler(on_signal),
        SaFlags::empty(),
        SigSet::empty(),
    );
    for s in [Signal::SIGINT, Signal::SIGTERM, Signal::SIGHUP] {
        // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
        let _ = unsafe { sigaction(s, &sa) };
    }
}

pub(super) fn open_pty() -> anyhow::Result<(OwnedFd, OwnedFd, PathBuf)> {
    let pty = nix::pty::openpty(None, None).context("openpty")?;
    let mut t = termios::tcgetattr(&pty.slave).context("tcgetattr")?;
    termios::cfmakeraw(&mut t);
    termios::tcsetattr(&pty.slave, termios::SetArg::TCSANOW, &t).context("tcsetattr")?;
    let path = nix::unistd::ttyname(&pty.slave).context("ttyname")?;
    let flags = fcntl(&pty.master, FcntlArg::F_GETFL).context("fcntl")?;
    fcntl(
        &pty.master,
        FcntlArg::F_SETFL(OFlag::from_bits_truncate(flags) | OFlag::O_NONBLOCK),
    )
    .context("fcntl")?;
    Ok((pty.master, pty.slave, path))
}

/// `--link PATH` may name nothing yet, or a symlink to a pseudo-terminal (a stale link of an
/// earlier session, replaced). Anything else — a file, a directory, a device, a link to
/// anything else — is refused: the sim never destroys what a path points to.
pub(super) fn check_link_path(l: &std::path::Path) -> anyhow::Result<()> {
    match std::fs::symlink_metadata(l) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e).with_context(|| format!("--link {}", l.display())),
        Ok(m) if m.file_type().is_symlink() => {
            let target =
                std::fs::read_link(l).with_context(|| format!("--link {}", l.display()))?;
            if target.starts_with("/dev/pts/") {
                Ok(())
            } else {
                anyhow::bail!(
                    "--link {}: exists and links to {}, not to a pseudo-terminal; refusing to \
                     replace it (choose another path)",
                    l.display(),
                    target.display()
                )
            }
        }
        Ok(_) => anyhow::bail!(
            "--link {}: exists and is not a symlink; refusing to replace it (choose another path)",
            l.display()
        ),
    }
}
