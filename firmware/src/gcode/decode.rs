//! The known G/M/T codes: each family's module parses its own codes ([`motion`], [`heat`],
//! [`pause`], [`report`], [`settings`], [`driver`], [`sd`], [`recovery`]); this module asks
//! them in turn and builds the [`Command`] of the one that knows the code.

use super::words::Words;
use super::{
    driver, err, heat, motion, pause, recovery, report, sd, settings, Command, ParseError,
    ParseErrorKind,
};

/// Build a known command from its code and words; `None` = unknown code.
pub(super) fn build_known(code: (u8, u16), w: &Words<'_>) -> Option<Result<Command, ParseError>> {
    let r = (|| -> Result<Option<Command>, ParseError> {
        if let Some(c) = motion::build(code, w)? {
            return Ok(Some(Command::Motion(c)));
        }
        if let Some(c) = heat::build(code, w)? {
            return Ok(Some(Command::Heat(c)));
        }
        if let Some(c) = pause::build(code, w)? {
            return Ok(Some(Command::Pause(c)));
        }
        let c = match code {
            (b'M', n) if settings::is_settings_code(n) => Command::Settings(settings::build(n, w)?),
            (b'M', n) if sd::is_sd_code(n, w) => Command::Sd(sd::build(n, w)?),
            (b'M', n) if report::is_report_code(n) => Command::Report(report::build(n, w)?),
            (b'M', n) if driver::is_driver_code(n) => Command::Driver(driver::build(n, w)?),
            (b'M', n) if recovery::is_recovery_code(n) => Command::Recovery(recovery::build(w)?),
            (b'T', n) => {
                w.check(b"", b"")?;
                match u8::try_from(n) {
                    Ok(t) => Command::Tool(t),
                    Err(_) => return Err(err(ParseErrorKind::OutOfRange, 0)),
                }
            }
            _ => return Ok(None),
        };
        Ok(Some(c))
    })();
    match r {
        Ok(Some(c)) => Some(Ok(c)),
        Ok(None) => None,
        Err(e) => Some(Err(e)),
    }
}
