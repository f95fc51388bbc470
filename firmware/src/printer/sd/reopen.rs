//! The card's side of M1000 for a job kept from the card (`printer/recovery.rs` has the
//! sequence): find the kept file again and check it is the one that was printing before the
//! file is fed from the kept offset.

use super::{CardRequest, SdJob};
use crate::link::{FileLines, PortId};
use crate::printer::Printer;
use crate::storage::sd::{Card, CardError};
use embedded_sdmmc::BlockDevice;

/// Why a kept SD job cannot continue from its offset (M1000).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::printer) enum ReopenError {
    /// The card or the file could not be had.
    Card(CardError),
    /// The file's size is not the kept one, or the offset is not the first byte of a line:
    /// not the file that was printing.
    Changed { size: u32 },
}

impl core::fmt::Display for ReopenError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ReopenError::Card(CardError::NoCard) => f.write_str("No media"),
            ReopenError::Card(e) => write!(f, "open failed ({e})"),
            ReopenError::Changed { size } => write!(
                f,
                "the file changed (now {size} bytes, or the kept offset is not a line start)"
            ),
        }
    }
}

impl Printer {
    /// A driver services a card slot.
    pub(in crate::printer) fn card_attached(&self) -> bool {
        self.sd.attached
    }

    /// M1000 asks for the card (its `ok` waits for the answer; see `recovery.rs`).
    pub(in crate::printer) fn request_card_resume(&mut self) {
        let port = self.asking_port();
        self.sd.request = Some(CardRequest::Resume { port });
    }

    /// Select `name` to start at `offset` (a kept job's file, M1000): mounted when not yet
    /// (power-up), the file checked to be of `size` bytes and the offset to be the first byte
    /// of a line in it (byte 0, or the byte before it a line end), so a file replaced since the
    /// power cut is not fed from the middle of a line. `File opened` / `File selected` go to
    /// `port` as for M23.
    pub(in crate::printer) fn sd_select_at<D: BlockDevice>(
        &mut self,
        card: &mut Card<D>,
        port: Option<PortId>,
        name: &str,
        offset: u32,
        size: u32,
    ) -> Result<(), ReopenError>
    where
        D::Error: core::fmt::Debug,
    {
        self.sd.job = SdJob::None;
        if !self.sd.mounted {
            // Power-up, or a card inserted or released (M22) since: mount it now.
            self.sd.mounted = card.mount().is_ok();
            if self.sd.mounted {
                self.sd.released = false;
            }
        }
        if !self.sd.mounted {
            return Err(ReopenError::Card(CardError::NoCard));
        }
        let e = card.open(name).map_err(ReopenError::Card)?;
        let line_start = match offset.checked_sub(1) {
            _ if e.size != size => false,
            None => true,
            Some(before) if offset <= e.size => {
                let mut b = [0u8; 1];
                let n = card.read_at(before, &mut b).map_err(ReopenError::Card)?;
                n == 1 && FileLines::is_line_end(b[0])
            }
            Some(_) => false,
        };
        if !line_start {
            card.close();
            return Err(ReopenError::Changed { size: e.size });
        }
        self.select_entry(port, &e, offset);
        Ok(())
    }

    /// Forget the selected file (M1000 refused after [`Printer::sd_select_at`]).
    pub(in crate::printer) fn sd_unselect<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        if !self.sd_printing() {
            self.sd.job = SdJob::None;
            card.close();
        }
    }
}
