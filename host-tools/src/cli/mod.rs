//! Command-line front ends, one module per subcommand. Each module owns its `Args` (clap) and a
//! `run` function; `main.rs` only dispatches.

pub mod additive;
pub mod compile;
pub mod cure_check;
pub mod grow;
pub mod preview;
pub mod range;
pub mod send;
pub mod stats;
pub mod timebased;

/// Checks that `gcode` reads back with the project's own reader (the firmware's parser): every
/// number within its range, every line valid. Generated G-code that fails is a bug or an input
/// beyond the limits; it is refused before anything is written.
pub(crate) fn check_readable(gcode: &[u8]) -> anyhow::Result<()> {
    use crate::gcode::read::GcodeReader as _;
    crate::gcode::read::default_reader()
        .read(gcode, &mut |_| {})
        .map_err(|e| {
            anyhow::anyhow!("the generated G-code would not be readable ({e}); nothing written")
        })?;
    Ok(())
}

/// Write `model` as G-code to `output` with `writer` (checked readable, written with
/// [`crate::fileio::write_output`]), then, if asked, render a preview of the G-code to
/// `preview` (the commands that generate jobs share this last step).
pub(crate) fn write_gcode(
    writer: &crate::design::writer::GcodeWriter,
    model: &crate::design::model::Model,
    output: &std::path::Path,
    preview: Option<&std::path::Path>,
    profile: &crate::design::profile::Profile,
) -> anyhow::Result<crate::design::writer::WriteSummary> {
    let mut buf = Vec::new();
    let summary = writer.write_into(model, &mut buf)?;
    check_readable(&buf)?;
    crate::fileio::write_bytes(output, &buf)?;
    if let Some(pv) = preview {
        crate::job::preview::render(
            &buf,
            profile,
            pv,
            &crate::job::preview::PreviewOptions::default(),
        )?;
    }
    Ok(summary)
}

/// `--profile help` (or `list`): prints the built-in printer profiles and returns true, so the
/// command stops there with success.
pub(crate) fn list_profiles_if_asked(name: &str) -> anyhow::Result<bool> {
    if !matches!(name, "help" | "list") {
        return Ok(false);
    }
    crate::fileio::say(format_args!(
        "printer profiles (built in; a TOML file's path works too, see docs/profiles.md):\n{}",
        crate::design::profile::listing().trim_end()
    ))?;
    Ok(true)
}
