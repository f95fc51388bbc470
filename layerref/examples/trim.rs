//! Trim a real slicer file for the layer corpus (docs/testing.md, "The real-file corpus"):
//! `cargo run -p layerref --example trim -- IN OUT --layers K [--max-bytes N]`.
//!
//! Keeps, line for line as the slicer wrote them:
//! - everything before the reference's layer K+1 (comments kept: the slicer's own markers): the
//!   header, the start code and the first K layers;
//! - everything after the file's last extrusion: the end code;
//!
//! and drops, between them, the layers above K. Comment blocks that only hold the slicer's
//! settings are dropped wherever they are (`; CONFIG_BLOCK_START` … `; CONFIG_BLOCK_END`,
//! `; prusaslicer_config = begin` … `end` and its SuperSlicer/Slic3r twins, Cura's `;SETTING_3`
//! lines): they say nothing to a printer. Where layers were dropped, a `G92 E<e>` gives E the
//! value the original file had there (an absolute-E end code retracts from the whole print's
//! E). With `--max-bytes`, K is lowered (down to 3) until the result fits. The first line of
//! the output says what was kept.

use layerref::read::{Item, Reader};
use layerref::{Comments, Model};

/// Whether a line opens (`Some(true)`) or closes (`Some(false)`) a settings block.
fn settings_block(line: &str) -> Option<bool> {
    let t = line.trim_start_matches(|c: char| c == ';' || c.is_whitespace());
    let t = t.trim_end();
    let lower = t.to_ascii_lowercase();
    if t == "CONFIG_BLOCK_START" || (lower.ends_with("_config = begin")) {
        Some(true)
    } else if t == "CONFIG_BLOCK_END" || lower.ends_with("_config = end") {
        Some(false)
    } else {
        None
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse::<usize>().ok())
    };
    let files: Vec<&String> = args
        .iter()
        .enumerate()
        .filter(|(i, a)| {
            let is_value = *i > 0 && matches!(args[i - 1].as_str(), "--layers" | "--max-bytes");
            !a.starts_with("--") && !is_value
        })
        .map(|(_, a)| a)
        .collect();
    let (Some(input), Some(output), Some(mut layers)) =
        (files.first(), files.get(1), value("--layers"))
    else {
        eprintln!("usage: trim IN OUT --layers K [--max-bytes N]");
        std::process::exit(2);
    };
    let max_bytes = value("--max-bytes");
    let raw = match std::fs::read(input) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("{input}: {e}");
            std::process::exit(1);
        }
    };
    // Slicers write comments in any encoding: keep the bytes, read them lossily.
    let text = String::from_utf8_lossy(&raw);
    let lines: Vec<&str> = text.lines().collect();
    let model = Model::of_lines(lines.iter().copied(), Comments::Keep);
    let last_extrusion = (0..lines.len()).rev().find(|&i| model.extrudes(i));
    // E (as written) after each line.
    let mut reader = Reader::default();
    let mut e_after = Vec::with_capacity(lines.len());
    let mut e = 0.0;
    for l in &lines {
        if let Item::Move { to, .. } = reader.line(l, false) {
            e = to[3];
        }
        if l.trim_start().to_ascii_uppercase().starts_with("G92") {
            // The reader keeps G92's E too (positions as the G-code writes them).
            if let Item::Move { to, .. } = reader.line("G1", false) {
                e = to[3];
            }
        }
        e_after.push(e);
    }
    let mut in_settings = false;
    let keep_line: Vec<bool> = lines
        .iter()
        .map(|l| match settings_block(l) {
            Some(open) => {
                in_settings = open;
                false
            }
            None => !in_settings && !l.starts_with(";SETTING_3"),
        })
        .collect();
    loop {
        let cut = model
            .layers()
            .iter()
            .find(|l| l.number as usize == layers + 1)
            .map_or(lines.len(), |l| l.first_line);
        let tail = last_extrusion.map_or(lines.len(), |i| i + 1).max(cut);
        let note = format!(
            "; layer corpus: trimmed from {} to its first {layers} layers and its end code \
             (lines {}..{} dropped; settings comment blocks dropped)",
            std::path::Path::new(input.as_str())
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned()),
            cut + 1,
            tail
        );
        let mut out = String::with_capacity(raw.len().min(1 << 20));
        out.push_str(&note);
        out.push('\n');
        for (i, l) in lines.iter().enumerate() {
            if i == tail && tail > cut {
                let before = cut.checked_sub(1).map_or(0.0, |k| e_after[k]);
                let there = e_after[tail - 1];
                if (there - before).abs() > 1e-9 {
                    out.push_str(&format!(
                        "G92 E{there:.5} ; layer corpus: E as the original file has it here\n"
                    ));
                }
            }
            if (i < cut || i >= tail) && keep_line[i] {
                out.push_str(l);
                out.push('\n');
            }
        }
        if max_bytes.is_some_and(|m| out.len() > m) && layers > 3 {
            layers -= 1;
            continue;
        }
        if let Err(e) = std::fs::write(output, out.as_bytes()) {
            eprintln!("{output}: {e}");
            std::process::exit(1);
        }
        println!("{output}: {layers} layers, {} bytes", out.len());
        break;
    }
}
