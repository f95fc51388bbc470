//! What a comment says about layers: the slicers' layer markers, the headers that name a
//! marker family before its first marker, and the heights some of them give.

/// Marker families, recognised by what the file writes (never by its header); the first one
/// seen in a job locks for the rest of it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Family {
    /// PrusaSlicer, SuperSlicer, Slic3r PE, OrcaSlicer (generic printers): `;LAYER_CHANGE`.
    Prusa,
    /// BambuStudio, OrcaSlicer for Bambu printers, Creality Print 5+: `; CHANGE_LAYER`.
    Bambu,
    /// Cura, ideaMaker, MatterControl, Creality Print 4: `;LAYER:<n>` (`; LAYER:<n>`).
    Cura,
    /// Simplify3D: `; layer <n>, Z = <mm>`.
    Simplify3d,
    /// FlashPrint: `;layer:<layer height>` (lower case, a decimal).
    FlashPrint,
    /// KISSlicer: `; BEGIN_LAYER_OBJECT z=<mm>`.
    KisSlicer,
    /// Kiri:Moto: `;; --- layer <n> (<height> @ <z>) ---`.
    KiriMoto,
    /// IceSL: `; <layer>`.
    IceSl,
    /// Klipper: `SET_PRINT_STATS_INFO CURRENT_LAYER=<n>` (a command).
    Klipper,
    /// `M73 L<n>` (a command).
    M73,
    /// This project's host compiler: `;TURN`, `;TURN:<n>`.
    Turn,
}

/// What a comment says about layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum CommentMarker {
    /// A layer starts (family, whether it is our turn marker, height if the marker gives it).
    Layer(Family, bool, Option<i32>),
    /// `;Z:<mm>` / `; Z_HEIGHT: <mm>`: height of the pending layer.
    Z(i32),
}

fn strip_prefix_ci<'a>(s: &'a [u8], prefix: &[u8]) -> Option<&'a [u8]> {
    let head = s.get(..prefix.len())?;
    if head.eq_ignore_ascii_case(prefix) {
        s.get(prefix.len()..)
    } else {
        None
    }
}

pub(super) fn trim(s: &[u8]) -> &[u8] {
    let start = s.iter().position(|c| !c.is_ascii_whitespace());
    let end = s.iter().rposition(|c| !c.is_ascii_whitespace());
    match (start, end) {
        (Some(a), Some(b)) => s.get(a..=b).unwrap_or(&[]),
        _ => &[],
    }
}

/// A decimal in mm → µm, if the text is one.
fn mm_to_um(s: &[u8]) -> Option<i32> {
    let v = crate::gcode::decimal(trim(s))?;
    if !v.is_finite() || v.abs() > 1.0e6 {
        return None;
    }
    Some(libm::roundf(v * 1000.0) as i32)
}

/// Whether the text is a layer number: digits, or a negative number (Cura's raft layers).
fn is_layer_number(s: &[u8]) -> bool {
    let digits = s.strip_prefix(b"-").unwrap_or(s);
    !digits.is_empty() && digits.iter().all(u8::is_ascii_digit)
}

/// The text of a comment without the characters that frame it: leading `;` (Kiri:Moto writes
/// `;;`), spaces, and trailing spaces.
fn body(c: &[u8]) -> &[u8] {
    let start = c
        .iter()
        .position(|b| *b != b';' && !b.is_ascii_whitespace())
        .unwrap_or(c.len());
    trim(c.get(start..).unwrap_or(&[]))
}

/// The number after `key` in `text` (`z=0.263`, `Z = 0.6`, `@ 0.45`), mm → µm.
fn height_after(text: &[u8], key: &[u8]) -> Option<i32> {
    let at = text.windows(key.len()).position(|w| w == key)?;
    let rest = text.get(at + key.len()..)?;
    let rest = trim(rest);
    let end = rest
        .iter()
        .position(|b| !(b.is_ascii_digit() || *b == b'.' || *b == b'-'))
        .unwrap_or(rest.len());
    mm_to_um(rest.get(..end)?)
}

/// Whether the text is a decimal with a fraction (`0.19`): FlashPrint's layer height.
fn is_fraction(s: &[u8]) -> bool {
    s.contains(&b'.') && crate::gcode::decimal(s).is_some()
}

/// Classify one comment (the text after `;`). Every family with or without a space after the
/// `;` (`;LAYER:3`, `; LAYER:3`, `;; --- layer 3 …`).
pub(super) fn classify_comment(c: &[u8]) -> Option<CommentMarker> {
    use CommentMarker::Layer;
    let t = body(c);
    let marker = |f: Family, z: Option<i32>| Some(Layer(f, false, z));
    match t {
        b"LAYER_CHANGE" => return marker(Family::Prusa, None),
        b"CHANGE_LAYER" => return marker(Family::Bambu, None),
        b"<layer>" => return marker(Family::IceSl, None),
        b"TURN" => return Some(Layer(Family::Turn, true, None)),
        _ => {}
    }
    if let Some(rest) = t
        .strip_prefix(b"Z:")
        .or_else(|| t.strip_prefix(b"Z_HEIGHT:"))
    {
        return mm_to_um(rest).map(CommentMarker::Z);
    }
    if let Some(rest) = t.strip_prefix(b"LAYER:") {
        return is_layer_number(trim(rest)).then_some(Layer(Family::Cura, false, None));
    }
    if let Some(rest) = t.strip_prefix(b"layer:") {
        return is_fraction(trim(rest)).then_some(Layer(Family::FlashPrint, false, None));
    }
    if let Some(rest) = t.strip_prefix(b"TURN:") {
        return is_layer_number(trim(rest)).then_some(Layer(Family::Turn, true, None));
    }
    if t.starts_with(b"BEGIN_LAYER_OBJECT") {
        return marker(Family::KisSlicer, height_after(t, b"z="));
    }
    // Kiri:Moto: "--- layer 12 (0.200 @ 2.45) ---".
    if let Some(rest) = t.strip_prefix(b"--- layer ") {
        let digits = rest.iter().take_while(|c| c.is_ascii_digit()).count();
        if digits > 0 {
            return marker(Family::KiriMoto, height_after(rest, b"@"));
        }
    }
    // Simplify3D: "layer 12, Z = 2.600".
    if let Some(rest) = strip_prefix_ci(t, b"layer ") {
        let digits = rest.iter().take_while(|c| c.is_ascii_digit()).count();
        if digits > 0 && matches!(rest.get(digits), None | Some(b',')) {
            return marker(Family::Simplify3d, height_after(rest, b"Z ="));
        }
    }
    None
}
