//! Layer boundaries of a job as the firmware's layer detector sees them.
//!
//! Stand-in until `firmware::layer` (fw-front) lands: recognises PrusaSlicer's
//! `;LAYER_CHANGE` and Cura's `;LAYER:<n>` comments only. Replace with the firmware's detector.

/// For each line, the layer number that starts there (0-based), if any.
pub fn detect(lines: &[String]) -> Vec<Option<u32>> {
    let mut n: u32 = 0;
    lines
        .iter()
        .map(|l| {
            let t = l.trim();
            if t.starts_with(";LAYER_CHANGE") || t.starts_with(";LAYER:") {
                let this = n;
                n += 1;
                Some(this)
            } else {
                None
            }
        })
        .collect()
}
