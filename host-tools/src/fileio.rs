//! Every file the tools read or write goes through here: one bounded reader, one safe output
//! writer and one checked standard output.
//!
//! **Reading** ([`read_bounded`]): at most a per-kind limit ([`Limit`]) is read; a longer input
//! (or an endless one such as `/dev/zero`) is an error after reading one byte past the limit,
//! so memory never grows beyond the limit.
//!
//! **Writing** ([`write_output`]) never destroys what a path pointed to:
//! - a path that does not exist, or names a regular file, is written to a temporary file
//!   (`.NAME.tmp-PID`) in the same directory, flushed, synced and renamed into place: readers
//!   see the old file or the whole new one, never a half-written one. An existing file's
//!   permissions are kept. On any error the temporary file is removed.
//! - a symbolic link is followed: the file it points to is replaced as above, the link stays a
//!   link. A link that points nowhere is refused.
//! - a device, FIFO or socket (`/dev/null`, `/dev/stdout`, a pipe) is written through directly;
//!   it is never replaced by a regular file.
//! - a directory is refused before anything is created.
//!
//! Every write error (a full disk, `/dev/full`, a closed pipe) is an error with the path, never
//! a panic, and the command exits non-zero.
//!
//! **Standard output** ([`say`]): summary lines go through a checked write; a closed or failing
//! stdout is an error (exit status 1), not a panic.

use anyhow::{bail, Context};
use std::fs::{self, File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Largest input of each kind, bytes. Chosen well above real files (a 45k-point helix is
/// 1.5 MB of G-code; a large slicer job is ~100 MB; a detailed STL ~50 MB) and low enough that
/// reading the whole file into memory is harmless.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    /// G-code and time-based G-code: 1 GiB.
    Gcode,
    /// STL meshes: 512 MiB.
    Stl,
    /// Design scripts (Rhai): 16 MiB.
    Script,
    /// Printer profiles (TOML): 1 MiB.
    Profile,
    /// Boundary files (SVG or `x y` lines) and pictures (PNG): 64 MiB.
    Drawing,
}

impl Limit {
    /// The limit in bytes.
    pub const fn bytes(self) -> u64 {
        match self {
            Limit::Gcode => 1 << 30,
            Limit::Stl => 512 << 20,
            Limit::Script => 16 << 20,
            Limit::Profile => 1 << 20,
            Limit::Drawing => 64 << 20,
        }
    }
}

/// Reads `path` whole, refusing inputs longer than `limit`.
pub fn read_bounded(path: &Path, limit: Limit) -> anyhow::Result<Vec<u8>> {
    read_at_most(path, limit.bytes())
}

/// Reads `path` whole as UTF-8 text, refusing inputs longer than `limit`.
pub fn read_text_bounded(path: &Path, limit: Limit) -> anyhow::Result<String> {
    let bytes = read_bounded(path, limit)?;
    String::from_utf8(bytes).map_err(|e| {
        anyhow::anyhow!(
            "{}: not UTF-8 text (byte {})",
            path.display(),
            e.utf8_error().valid_up_to()
        )
    })
}

/// Reads at most `max_bytes` of `path`; more is an error.
pub fn read_at_most(path: &Path, max_bytes: u64) -> anyhow::Result<Vec<u8>> {
    let file = File::open(path).with_context(|| format!("reading {}", path.display()))?;
    let meta = file
        .metadata()
        .with_context(|| format!("reading {}", path.display()))?;
    if meta.is_dir() {
        bail!("reading {}: is a directory", path.display());
    }
    if meta.is_file() && meta.len() > max_bytes {
        bail!(
            "reading {}: {} bytes, more than the {} bytes this input may have",
            path.display(),
            meta.len(),
            max_bytes
        );
    }
    let mut buf = Vec::new();
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut buf)
        .with_context(|| format!("reading {}", path.display()))?;
    if buf.len() as u64 > max_bytes {
        bail!(
            "reading {}: longer than the {} bytes this input may have",
            path.display(),
            max_bytes
        );
    }
    Ok(buf)
}

/// Where [`write_output`] puts the bytes.
enum Target {
    /// Replace this regular file (or create it) through a temporary file and a rename.
    Replace(PathBuf),
    /// Write straight into an existing device, FIFO or socket.
    Through,
}

fn target_of(path: &Path) -> anyhow::Result<Target> {
    match fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Target::Replace(path.into())),
        Err(e) => Err(e).with_context(|| format!("writing {}", path.display())),
        Ok(link) => {
            let meta = match fs::metadata(path) {
                Ok(m) => m,
                Err(e) if link.file_type().is_symlink() => {
                    bail!(
                        "writing {}: a symbolic link to nothing ({e}); not replacing the link",
                        path.display()
                    )
                }
                Err(e) => return Err(e).with_context(|| format!("writing {}", path.display())),
            };
            if meta.is_dir() {
                bail!(
                    "writing {}: is a directory; give a file name",
                    path.display()
                );
            }
            if !meta.is_file() {
                return Ok(Target::Through);
            }
            if link.file_type().is_symlink() {
                let real = fs::canonicalize(path)
                    .with_context(|| format!("resolving the link {}", path.display()))?;
                return Ok(Target::Replace(real));
            }
            Ok(Target::Replace(path.into()))
        }
    }
}

/// Writes an output file without destroying what `path` pointed to (see the module docs):
/// `fill` gets a buffered writer; its error, or any write error, leaves the old file intact.
pub fn write_output<T>(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    match target_of(path)? {
        Target::Through => {
            let f = OpenOptions::new()
                .write(true)
                .open(path)
                .with_context(|| format!("opening {}", path.display()))?;
            let mut w = std::io::BufWriter::new(f);
            let v = fill(&mut w).with_context(|| format!("writing {}", path.display()))?;
            w.flush()
                .with_context(|| format!("writing {}", path.display()))?;
            Ok(v)
        }
        Target::Replace(real) => {
            let dir = match real.parent() {
                Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
                _ => PathBuf::from("."),
            };
            let name = real
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "output".into());
            let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
            let result = write_replace(&real, &tmp, fill);
            if result.is_err() {
                let _ = fs::remove_file(&tmp);
            }
            result.with_context(|| format!("writing {}", path.display()))
        }
    }
}

fn write_replace<T>(
    real: &Path,
    tmp: &Path,
    fill: impl FnOnce(&mut dyn Write) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    let f = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(tmp)
        .with_context(|| format!("creating {}", tmp.display()))?;
    if let Ok(old) = fs::metadata(real) {
        // Keep the replaced file's permissions (best effort: a foreign owner may forbid it).
        let _ = f.set_permissions(old.permissions());
    }
    let mut w = std::io::BufWriter::new(f);
    let v = fill(&mut w)?;
    let f = w.into_inner().map_err(|e| e.into_error())?;
    f.sync_all()?;
    drop(f);
    fs::rename(tmp, real)?;
    Ok(v)
}

/// Refuses output paths that name one of the `inputs` — the same file, through any link or
/// hard link (`same-file` compares device and inode): writing it would replace what the
/// command reads (before, `compile d.rhai -o d.rhai` replaced the design with its G-code).
/// An input that does not exist (a built-in profile's name) names no file.
pub fn refuse_inputs_as_outputs(outputs: &[&Path], inputs: &[&Path]) -> anyhow::Result<()> {
    for o in outputs {
        for i in inputs {
            if same_file::is_same_file(o, i).unwrap_or(false) {
                anyhow::bail!(
                    "{}: that is the input {}; writing it would destroy it (choose another \
                     output)",
                    o.display(),
                    i.display()
                );
            }
        }
    }
    Ok(())
}

/// Writes `bytes` to `path` with [`write_output`].
pub fn write_bytes(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    write_output(path, |w| Ok(w.write_all(bytes)?))
}

/// Writes a summary line to standard output; a closed or failing stdout is an error.
pub fn say(line: impl std::fmt::Display) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{line}")
        .and_then(|()| out.flush())
        .context("writing to standard output")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("ht-fileio-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).expect("dir");
        d
    }

    #[test]
    fn endless_input_stops_at_the_limit() {
        let e = read_at_most(Path::new("/dev/zero"), 1000).expect_err("endless");
        assert!(e.to_string().contains("longer than the 1000 bytes"), "{e}");
    }

    #[test]
    fn regular_file_over_the_limit_is_refused_before_reading() {
        let d = dir("big");
        let p = d.join("a");
        fs::write(&p, [b'x'; 100]).expect("write");
        assert!(read_at_most(&p, 99).is_err());
        assert_eq!(read_at_most(&p, 100).expect("fits").len(), 100);
    }

    #[test]
    fn symlink_is_written_through_and_stays_a_link() {
        let d = dir("link");
        let real = d.join("real.gcode");
        fs::write(&real, "old").expect("write");
        let link = d.join("link.gcode");
        std::os::unix::fs::symlink(&real, &link).expect("symlink");
        write_bytes(&link, b"new").expect("write through");
        assert!(fs::symlink_metadata(&link)
            .expect("meta")
            .file_type()
            .is_symlink());
        assert_eq!(fs::read_to_string(&real).expect("read"), "new");
        let names: Vec<_> = fs::read_dir(&d).expect("ls").collect();
        assert_eq!(names.len(), 2, "no temporary file left");
    }

    #[test]
    fn dangling_link_and_directory_are_refused_without_leftovers() {
        let d = dir("refuse");
        let link = d.join("dangling.gcode");
        std::os::unix::fs::symlink(d.join("nowhere"), &link).expect("symlink");
        assert!(write_bytes(&link, b"x").is_err());
        let sub = d.join("sub");
        fs::create_dir(&sub).expect("mkdir");
        let e = write_bytes(&sub, b"x").expect_err("directory");
        assert!(e.to_string().contains("is a directory"), "{e}");
        let mut names: Vec<_> = fs::read_dir(&d)
            .expect("ls")
            .map(|e| e.expect("entry").file_name())
            .collect();
        names.sort();
        assert_eq!(names, ["dangling.gcode", "sub"]);
    }

    #[test]
    fn failed_fill_keeps_the_old_file() {
        let d = dir("keep");
        let p = d.join("out.gcode");
        fs::write(&p, "old").expect("write");
        let r: anyhow::Result<()> = write_output(&p, |w| {
            w.write_all(b"partial")?;
            bail!("model error")
        });
        assert!(r.is_err());
        assert_eq!(fs::read_to_string(&p).expect("read"), "old");
        assert_eq!(fs::read_dir(&d).expect("ls").count(), 1);
    }

    #[test]
    fn device_is_written_through_and_full_device_is_an_error() {
        write_bytes(Path::new("/dev/null"), b"x").expect("/dev/null");
        use std::os::unix::fs::FileTypeExt;
        let kind = fs::metadata("/dev/null").expect("meta").file_type();
        assert!(kind.is_char_device(), "/dev/null is still a device");
        let e = write_bytes(Path::new("/dev/full"), &[b'x'; 100_000]).expect_err("full");
        assert!(format!("{e:#}").contains("/dev/full"), "{e:#}");
    }
}
