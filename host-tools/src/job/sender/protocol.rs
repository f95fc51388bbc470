//! The host side of the serial protocol spoken by Marlin-style firmware (and ours): framing of
//! outgoing lines (`N<n> <line>*<xor>`) and classification of every line the printer sends back
//! (`ok`, `Resend:`, `busy:`, `echo:`, `Error:`, temperature reports, `//action:` notifications,
//! the M115 report).
//!
//! This reads the printer's *replies*; G-code itself is only ever read with the firmware's parser
//! (see [`crate::job`]).

/// XOR of all bytes of `s`: the checksum Marlin, RepRapFirmware and our firmware expect after `*`.
pub fn checksum(s: &str) -> u8 {
    s.bytes().fold(0u8, |acc, b| acc ^ b)
}

/// Frames one G-code line for sending: `N<n> <line>*<checksum>`. The caller strips comments and
/// surrounding blanks first (see [`strip_comment`]).
pub fn frame(line_no: u32, line: &str) -> String {
    let body = format!("N{line_no} {line}");
    let cs = checksum(&body);
    format!("{body}*{cs}")
}

/// The G-code part of a line without its `;` comment and surrounding blanks. Parenthesised
/// comments are left to the firmware's parser. Returns an empty string for comment-only lines.
pub fn strip_comment(line: &str) -> &str {
    match line.find(';') {
        Some(i) => line.get(..i).unwrap_or("").trim(),
        None => line.trim(),
    }
}

/// The `Last Line: L` of a line error (`checksum mismatch, Last Line: 18`, `Line Number is not
/// Last Line Number+1, Last Line: 17`: Marlin's and our firmware's spelling), if any.
pub fn last_line(error: &str) -> Option<u32> {
    let at = error.rfind("Last Line:")?;
    let rest = error.get(at + "Last Line:".len()..)?.trim_start();
    let digits: &str = rest
        .get(
            ..rest
                .find(|c: char| !c.is_ascii_digit())
                .unwrap_or(rest.len()),
        )
        .unwrap_or("");
    digits.parse().ok()
}

/// True for the link-level errors of Marlin and our firmware (checksum, line number), which
/// mean the line was not taken.
pub fn is_link_error(error: &str) -> bool {
    error.contains("checksum") || error.contains("Checksum") || error.contains("Line Number")
}

/// An `//action:` notification (OctoPrint's spellings).
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// The printer asks the host to pause (e.g. the pause button on the board).
    Pause,
    /// The printer has paused (parked).
    Paused,
    /// The printer asks the host to resume.
    Resume,
    /// The printer has resumed.
    Resumed,
    /// The printer asks the host to cancel the job.
    Cancel,
    /// Free text for the user.
    Notification(String),
    /// Any other action name with its argument text.
    Other(String),
}

/// Temperatures from an `ok T:..` reply or an auto-report line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Temps {
    /// Hot-end temperature, °C.
    pub hotend_c: Option<f32>,
    /// Hot-end target, °C.
    pub hotend_target_c: Option<f32>,
    /// Bed temperature, °C.
    pub bed_c: Option<f32>,
    /// Bed target, °C.
    pub bed_target_c: Option<f32>,
}

impl Temps {
    /// True when at least one reading was found.
    pub fn any(&self) -> bool {
        self.hotend_c.is_some() || self.bed_c.is_some()
    }
}

/// One line from the printer, classified.
#[derive(Clone, Debug, PartialEq)]
pub enum Response {
    /// `ok`, possibly with a line number (`ok N12`) and/or temperatures (`ok T:..`).
    Ok {
        /// Line number acknowledged, when the firmware says it.
        line: Option<u32>,
        /// Temperatures carried on the `ok`, when any.
        temps: Option<Temps>,
    },
    /// `Resend: n` / `rs n`: resend from line `n`.
    Resend(u32),
    /// `busy: ...` (also `echo:busy: ...`): the printer is alive but working on a long command.
    Busy(String),
    /// `echo:...`: information for the user.
    Echo(String),
    /// `Error:...` / `!!`: an error. Checksum/line-number errors are followed by `Resend:`.
    Error(String),
    /// A temperature report without `ok` (auto-report or M105 on some firmware).
    Temperature(Temps),
    /// `//action:...`.
    Action(Action),
    /// The first line of the M115 report (`FIRMWARE_NAME:...`), text after the prefix.
    FirmwareInfo(String),
    /// A capability line of the M115 report: `Cap:NAME:0|1`.
    Capability {
        /// Capability name as sent, e.g. `AUTOREPORT_TEMP`.
        name: String,
        /// Whether it is enabled.
        enabled: bool,
    },
    /// `start`: the firmware (re)booted.
    Start,
    /// Anything else (kept for the log).
    Other(String),
}

impl Response {
    /// Classifies one line (without its line ending).
    pub fn parse(raw: &str) -> Response {
        let line = raw.trim();
        if line == "ok" || line.starts_with("ok ") {
            let rest = line.get(2..).unwrap_or("").trim();
            let mut number = None;
            if let Some(r) = rest.strip_prefix('N') {
                number = r
                    .split(|c: char| !c.is_ascii_digit())
                    .next()
                    .and_then(|d| d.parse().ok());
            }
            let temps = parse_temps(rest);
            return Response::Ok {
                line: number,
                temps: temps.any().then_some(temps),
            };
        }
        if let Some(n) = resend_line(line) {
            return Response::Resend(n);
        }
        if let Some(rest) = line.strip_prefix("//action:") {
            return Response::Action(parse_action(rest.trim()));
        }
        if let Some(rest) = line
            .strip_prefix("busy:")
            .or_else(|| line.strip_prefix("echo:busy:"))
        {
            return Response::Busy(rest.trim().to_string());
        }
        if let Some(rest) = line
            .strip_prefix("Error:")
            .or_else(|| line.strip_prefix("!!"))
        {
            return Response::Error(rest.trim().to_string());
        }
        if let Some(rest) = line.strip_prefix("echo:") {
            return Response::Echo(rest.trim().to_string());
        }
        if let Some(rest) = line.strip_prefix("FIRMWARE_NAME:") {
            return Response::FirmwareInfo(rest.trim().to_string());
        }
        if let Some(rest) = line.strip_prefix("Cap:") {
            let (name, flag) = match rest.rsplit_once(':') {
                Some((n, f)) => (n, f.trim()),
                None => (rest, "1"),
            };
            return Response::Capability {
                name: name.trim().to_string(),
                enabled: flag == "1",
            };
        }
        if line == "start" {
            return Response::Start;
        }
        if line.starts_with("T:") || line.starts_with("B:") || line.starts_with("T0:") {
            let temps = parse_temps(line);
            if temps.any() {
                return Response::Temperature(temps);
            }
        }
        Response::Other(line.to_string())
    }
}

fn resend_line(line: &str) -> Option<u32> {
    let rest = line
        .strip_prefix("Resend:")
        .or_else(|| line.strip_prefix("resend:"))
        .or_else(|| line.strip_prefix("rs "))?;
    let rest = rest.trim();
    let rest = rest.strip_prefix('N').unwrap_or(rest);
    rest.split(|c: char| !c.is_ascii_digit())
        .next()
        .and_then(|d| d.parse().ok())
}

fn parse_action(rest: &str) -> Action {
    let (name, arg) = match rest.split_once(' ') {
        Some((n, a)) => (n, a.trim()),
        None => (rest, ""),
    };
    match name {
        "pause" => Action::Pause,
        "paused" => Action::Paused,
        "resume" => Action::Resume,
        "resumed" => Action::Resumed,
        "cancel" => Action::Cancel,
        "notification" => Action::Notification(arg.to_string()),
        _ => Action::Other(rest.to_string()),
    }
}

/// Reads `T:210.0 /215.0 B:60 /60 @:0` style reports (first hot end only).
pub fn parse_temps(s: &str) -> Temps {
    let mut t = Temps::default();
    let mut words = s.split_whitespace().peekable();
    while let Some(w) = words.next() {
        let (key, val) = match w.split_once(':') {
            Some(kv) => kv,
            None => continue,
        };
        let slot = match key {
            "T" | "T0" => 0,
            "B" => 1,
            _ => continue,
        };
        let now: Option<f32> = val.parse().ok();
        let mut target = None;
        if let Some(next) = words.peek() {
            if let Some(tv) = next.strip_prefix('/') {
                target = tv.parse().ok();
                words.next();
            }
        }
        if slot == 0 && t.hotend_c.is_none() {
            t.hotend_c = now;
            t.hotend_target_c = target;
        } else if slot == 1 && t.bed_c.is_none() {
            t.bed_c = now;
            t.bed_target_c = target;
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_last_line_of_line_errors() {
        assert_eq!(last_line("checksum mismatch, Last Line: 18"), Some(18));
        assert_eq!(
            last_line("Line Number is not Last Line Number+1, Last Line: 17"),
            Some(17)
        );
        assert_eq!(
            last_line("No Checksum with line number, Last Line: 0"),
            Some(0)
        );
        assert_eq!(last_line("Printer halted. kill() called!"), None);
        assert_eq!(last_line("Last Line: x"), None);
        assert_eq!(last_line("Last Line: 99999999999999"), None);
        assert!(is_link_error("checksum mismatch"));
        assert!(!is_link_error("Printer halted. kill() called!"));
    }

    #[test]
    fn frames_like_marlin() {
        // Reference value computed by hand: XOR over "N1 G28".
        let f = frame(1, "G28");
        let expected = checksum("N1 G28");
        assert_eq!(f, format!("N1 G28*{expected}"));
        assert_eq!(checksum("N1 G28"), b"N1 G28".iter().fold(0, |a, b| a ^ b));
        assert_eq!(strip_comment("G1 X1 ; move"), "G1 X1");
        assert_eq!(strip_comment(";LAYER_CHANGE"), "");
    }

    #[test]
    fn classifies_replies() {
        assert_eq!(
            Response::parse("ok"),
            Response::Ok {
                line: None,
                temps: None
            }
        );
        assert!(matches!(
            Response::parse("ok N12 P15 B3"),
            Response::Ok { line: Some(12), .. }
        ));
        assert_eq!(Response::parse("Resend: 7"), Response::Resend(7));
        assert_eq!(Response::parse("rs N7"), Response::Resend(7));
        assert!(matches!(
            Response::parse("echo:busy: processing"),
            Response::Busy(_)
        ));
        assert!(matches!(
            Response::parse("Error:checksum mismatch, Last Line: 5"),
            Response::Error(_)
        ));
        assert_eq!(
            Response::parse("//action:paused"),
            Response::Action(Action::Paused)
        );
        assert_eq!(
            Response::parse("//action:notification Layer 3"),
            Response::Action(Action::Notification("Layer 3".into()))
        );
        assert_eq!(
            Response::parse("Cap:LAYER_PAUSE:1"),
            Response::Capability {
                name: "LAYER_PAUSE".into(),
                enabled: true
            }
        );
        match Response::parse("ok T:210.5 /215.0 B:59.9 /60.0 @:127 B@:0") {
            Response::Ok { temps: Some(t), .. } => {
                assert_eq!(t.hotend_c, Some(210.5));
                assert_eq!(t.hotend_target_c, Some(215.0));
                assert_eq!(t.bed_c, Some(59.9));
                assert_eq!(t.bed_target_c, Some(60.0));
            }
            other => panic!("unexpected {other:?}"),
        }
        assert!(matches!(
            Response::parse(" T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0"),
            Response::Temperature(_)
        ));
    }
}
