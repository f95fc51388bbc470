//! The session's terminal: the pseudo-terminal the host opens, the `--link` symlink check,
//! and the signals that end the session (also used by the emulated board's `--serve`,
//! `board-emu/src/serve.rs`).

use anyhow::Context;
use nix::fcntl::{fcntl, FcntlArg, OFlag};
use nix::sys::termios;
use std::os::fd::OwnedFd;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

/// Set by SIGINT, SIGTERM or SIGHUP once [`install_signals`] ran: the session should end.
pub static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: nix::libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

/// SIGINT, SIGTERM and SIGHUP set [`STOP`] instead of ending the process.
pub fn install_signals() {
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

/// A raw pseudo-terminal: its master end (non-blocking), its slave end and the slave's path.
pub fn open_pty() -> anyhow::Result<(OwnedFd, OwnedFd, PathBuf)> {
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

/// Whether nobody holds the pseudo-terminal whose master is `master` (the master then reports
/// a hang-up, `POLLHUP`, as long as its own process keeps no slave end open).
pub fn hung_up(master: std::os::fd::BorrowedFd<'_>) -> bool {
    use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
    let mut fds = [PollFd::new(master, PollFlags::POLLIN)];
    let _ = poll(&mut fds, PollTimeout::ZERO);
    fds[0]
        .revents()
        .is_some_and(|r| r.contains(PollFlags::POLLHUP))
}

/// Sleeps until one of `masters` has bytes to read or `d` passes (just `d` when there is none).
pub fn wait_readable(masters: &[std::os::fd::BorrowedFd<'_>], d: std::time::Duration) {
    use nix::poll::{PollFd, PollFlags};
    let mut fds: Vec<PollFd> = masters
        .iter()
        .map(|m| PollFd::new(*m, PollFlags::POLLIN))
        .collect();
    if fds.is_empty() {
        std::thread::sleep(d);
        return;
    }
    let _ = nix::poll::ppoll(
        &mut fds,
        Some(nix::sys::time::TimeSpec::from_duration(d)),
        None,
    );
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
