//! Command-line front ends, one module per subcommand. Each module owns its `Args` (clap) and a
//! `run` function; `main.rs` only dispatches.

pub mod additive;
pub mod compile;
pub mod cure_check;
pub mod grow;
pub mod preview;
pub mod send;
pub mod stats;
pub mod timebased;

/// Write `model` as G-code to `output` with `writer`, then, if asked, render a preview of the
/// written file to `preview` (the commands that generate jobs share this last step).
pub(crate) fn write_gcode(
    writer: &crate::writer::GcodeWriter,
    model: &crate::model::Model,
    output: &std::path::Path,
    preview: Option<&std::path::Path>,
    profile: &crate::profile::Profile,
) -> anyhow::Result<crate::writer::WriteSummary> {
    use anyhow::Context as _;
    let file =
        std::fs::File::create(output).with_context(|| format!("creating {}", output.display()))?;
    let summary = writer.write(model, std::io::BufWriter::new(file))?;
    if let Some(pv) = preview {
        let bytes = std::fs::read(output)?;
        crate::preview::render(
            &bytes,
            profile,
            pv,
            &crate::preview::PreviewOptions::default(),
        )?;
    }
    Ok(summary)
}
