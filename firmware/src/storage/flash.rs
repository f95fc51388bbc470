//! NOR flash for the settings store: a model with real erase/write semantics that can lose power
//! at any operation (for the sim and the tests), the bridge from the blocking NOR-flash traits
//! (what the board's flash driver and the model implement) to the async traits
//! sequential-storage is written against, and the executor that runs those futures to the end.
//!
//! The model behaves as the STM32F4's flash does where the store can tell: an erase sets a whole
//! sector to `0xFF`; a write can only clear bits (`stored & data`, so writing a word twice is
//! allowed, as on the F4, which has no ECC); writes and reads outside the area, and writes not
//! aligned to `WRITE` bytes, are errors. Power cuts: [`NorFlashModel::cut_power_at`] makes the
//! n-th write or erase from now fail half-way (a write programs the first half of its words and
//! some bits of the next; an erase sets the first half of the sector to `0xFF` and leaves the
//! rest as it was, or with [`Cut::PartialTail`] the second half), and every operation after it
//! fail, until [`NorFlashModel::restore_power`].

use core::future::Future;
use core::pin::pin;
use core::task::{Context, Poll, Waker};
use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Run a future to its end by polling it in a loop. The store's futures never wait for
/// anything (the flash operations under them are blocking), so this returns after one poll;
/// six lines of `core` instead of a dependency on an executor crate for the portable library.
pub fn block_on<T>(fut: impl Future<Output = T>) -> T {
    let mut fut = pin!(fut);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
            return v;
        }
    }
}

/// A blocking NOR flash seen through the async NOR-flash traits (each operation completes when
/// first polled). embassy-embedded-hal's `BlockingAsync` does the same, but would pull the
/// embassy HAL crates into every host build of the library.
pub struct Blocking<F>(pub F);

impl<F: ErrorType> embedded_storage_async::nor_flash::ErrorType for Blocking<F> {
    type Error = F::Error;
}

impl<F: ReadNorFlash> embedded_storage_async::nor_flash::ReadNorFlash for Blocking<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes)
    }

    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

impl<F: NorFlash> embedded_storage_async::nor_flash::NorFlash for Blocking<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.0.erase(from, to)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.0.write(offset, bytes)
    }
}

impl<F: MultiwriteNorFlash> embedded_storage_async::nor_flash::MultiwriteNorFlash for Blocking<F> {}

/// Why a model operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelError {
    /// The range is outside the flash.
    OutOfBounds,
    /// The offset or length is not a multiple of the write (or erase) size.
    NotAligned,
    /// The power was cut during (or before) this operation.
    PowerCut,
}

impl NorFlashError for ModelError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            ModelError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            ModelError::NotAligned => NorFlashErrorKind::NotAligned,
            ModelError::PowerCut => NorFlashErrorKind::Other,
        }
    }
}

/// A flash operation that changes the contents.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashOp {
    /// A write (programming words).
    Write,
    /// A sector erase.
    Erase,
}

/// How much of the operation a power cut lets through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// Half of it (see the module documentation).
    Partial,
    /// None of it: the power fails just before the operation starts (after the one before it
    /// completed).
    Before,
    /// Half of it, the other half of an erase: a write as [`Cut::Partial`]; an erase sets the
    /// *second* half of the sector to `0xFF` and leaves the first as it was (an interrupted
    /// erase leaves a pattern nobody can predict: both halves are tried).
    PartialTail,
}

/// A NOR flash of `mem.len()` bytes in sectors of `ERASE` bytes, programmed in words of `WRITE`
/// bytes. `B` holds the bytes (an array, a `Vec`, a borrowed slice).
pub struct NorFlashModel<B, const WRITE: usize, const ERASE: usize> {
    mem: B,
    /// Writes and erases left before the power is cut (`None`: the power stays on).
    cut_in: Option<u32>,
    /// What the cut lets through.
    cut_kind: Cut,
    /// The power is off: every operation fails.
    off: bool,
    /// Writes and erases done (for tests that count the operations of a save).
    ops: u32,
    /// Sector erases done.
    erases: u32,
    /// The operation the last power cut interrupted.
    cut_op: Option<FlashOp>,
}

impl<B: AsRef<[u8]> + AsMut<[u8]>, const WRITE: usize, const ERASE: usize>
    NorFlashModel<B, WRITE, ERASE>
{
    /// A model over `mem` (its length a whole number of sectors), contents as given (use
    /// [`Self::erased`] for a new part).
    pub fn new(mem: B) -> Self {
        Self {
            mem,
            cut_in: None,
            cut_kind: Cut::Partial,
            off: false,
            ops: 0,
            erases: 0,
            cut_op: None,
        }
    }

    /// A model over `mem`, every byte set to `0xFF` (an erased part).
    pub fn erased(mut mem: B) -> Self {
        mem.as_mut().fill(0xFF);
        Self::new(mem)
    }

    /// The bytes.
    pub fn bytes(&self) -> &[u8] {
        self.mem.as_ref()
    }

    /// The bytes, for tests that corrupt them.
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        self.mem.as_mut()
    }

    /// The backing store.
    pub fn into_inner(self) -> B {
        self.mem
    }

    /// Writes and erases done so far.
    pub fn ops(&self) -> u32 {
        self.ops
    }

    /// Sector erases done so far.
    pub fn erases(&self) -> u32 {
        self.erases
    }

    /// Cut the power during the `n`-th write or erase from now (0 = the next one), half-way
    /// through it.
    pub fn cut_power_at(&mut self, n: u32) {
        self.cut_power(n, Cut::Partial);
    }

    /// Cut the power at the `n`-th write or erase from now, letting `kind` of it through.
    pub fn cut_power(&mut self, n: u32, kind: Cut) {
        self.cut_in = Some(n);
        self.cut_kind = kind;
    }

    /// Power on again (after a cut): the flash keeps whatever the cut left.
    pub fn restore_power(&mut self) {
        self.cut_in = None;
        self.off = false;
    }

    /// The operation the last power cut interrupted.
    pub fn cut_op(&self) -> Option<FlashOp> {
        self.cut_op
    }

    /// True once a cut has happened (and the power has not been restored).
    pub fn is_off(&self) -> bool {
        self.off
    }

    /// Count an operation; true when the power fails during it.
    fn power_fails_now(&mut self, op: FlashOp) -> Result<bool, ModelError> {
        if self.off {
            return Err(ModelError::PowerCut);
        }
        self.ops = self.ops.saturating_add(1);
        match self.cut_in {
            Some(0) => {
                self.cut_in = None;
                self.off = true;
                self.cut_op = Some(op);
                Ok(true)
            }
            Some(n) => {
                self.cut_in = Some(n - 1);
                Ok(false)
            }
            None => Ok(false),
        }
    }

    fn range(&self, offset: u32, len: usize) -> Result<core::ops::Range<usize>, ModelError> {
        let start = offset as usize;
        let end = start.checked_add(len).ok_or(ModelError::OutOfBounds)?;
        if end > self.mem.as_ref().len() {
            return Err(ModelError::OutOfBounds);
        }
        Ok(start..end)
    }
}

impl<B, const WRITE: usize, const ERASE: usize> ErrorType for NorFlashModel<B, WRITE, ERASE> {
    type Error = ModelError;
}

impl<B: AsRef<[u8]> + AsMut<[u8]>, const WRITE: usize, const ERASE: usize> ReadNorFlash
    for NorFlashModel<B, WRITE, ERASE>
{
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), ModelError> {
        if self.off {
            return Err(ModelError::PowerCut);
        }
        let r = self.range(offset, bytes.len())?;
        bytes.copy_from_slice(&self.mem.as_ref()[r]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.mem.as_ref().len()
    }
}

impl<B: AsRef<[u8]> + AsMut<[u8]>, const WRITE: usize, const ERASE: usize> NorFlash
    for NorFlashModel<B, WRITE, ERASE>
{
    const WRITE_SIZE: usize = WRITE;
    const ERASE_SIZE: usize = ERASE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), ModelError> {
        if to < from {
            return Err(ModelError::OutOfBounds);
        }
        let r = self.range(from, (to - from) as usize)?;
        if !r.start.is_multiple_of(ERASE) || !r.end.is_multiple_of(ERASE) {
            return Err(ModelError::NotAligned);
        }
        for sector in r.step_by(ERASE) {
            let cut = self.power_fails_now(FlashOp::Erase)?;
            self.erases = self.erases.saturating_add(1);
            let mem = &mut self.mem.as_mut()[sector..sector + ERASE];
            if cut {
                match self.cut_kind {
                    Cut::Partial => mem[..ERASE / 2].fill(0xFF),
                    Cut::PartialTail => mem[ERASE / 2..].fill(0xFF),
                    Cut::Before => {}
                }
                return Err(ModelError::PowerCut);
            }
            mem.fill(0xFF);
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), ModelError> {
        let r = self.range(offset, bytes.len())?;
        if !r.start.is_multiple_of(WRITE) || !bytes.len().is_multiple_of(WRITE) {
            return Err(ModelError::NotAligned);
        }
        let cut = self.power_fails_now(FlashOp::Write)?;
        let mem = &mut self.mem.as_mut()[r];
        let done = if cut && self.cut_kind == Cut::Before {
            0
        } else if cut {
            // Half the words programmed; of the next word only the bits of every other nibble.
            let words = bytes.len() / WRITE;
            let whole = (words / 2) * WRITE;
            let partial = (whole + WRITE).min(bytes.len());
            for i in whole..partial {
                mem[i] &= bytes[i] | 0x0F;
            }
            whole
        } else {
            bytes.len()
        };
        for (m, b) in mem.iter_mut().zip(bytes).take(done) {
            *m &= *b;
        }
        if cut {
            Err(ModelError::PowerCut)
        } else {
            Ok(())
        }
    }
}

impl<B: AsRef<[u8]> + AsMut<[u8]>, const WRITE: usize, const ERASE: usize> MultiwriteNorFlash
    for NorFlashModel<B, WRITE, ERASE>
{
}

#[cfg(test)]
mod tests {
    use super::*;

    type Model = NorFlashModel<[u8; 64], 4, 32>;

    #[test]
    fn writes_only_clear_bits_and_erase_sets_ff() {
        let mut f = Model::erased([0; 64]);
        f.write(0, &[0x0F, 0xF0, 0x00, 0xFF]).unwrap();
        f.write(0, &[0xF3, 0xFF, 0xFF, 0x0F]).unwrap();
        assert_eq!(&f.bytes()[..4], &[0x03, 0xF0, 0x00, 0x0F]);
        f.erase(0, 32).unwrap();
        assert!(f.bytes()[..32].iter().all(|b| *b == 0xFF));
    }

    #[test]
    fn misaligned_and_out_of_bounds_are_errors() {
        let mut f = Model::erased([0; 64]);
        assert_eq!(f.write(2, &[0; 4]), Err(ModelError::NotAligned));
        assert_eq!(f.write(0, &[0; 3]), Err(ModelError::NotAligned));
        assert_eq!(f.write(64, &[0; 4]), Err(ModelError::OutOfBounds));
        assert_eq!(f.erase(0, 16), Err(ModelError::NotAligned));
        assert_eq!(f.erase(32, 96), Err(ModelError::OutOfBounds));
        assert!(
            f.bytes().iter().all(|b| *b == 0xFF),
            "a refused op changes nothing"
        );
    }

    #[test]
    fn a_power_cut_leaves_a_partial_write_and_stops_everything_after() {
        let mut f = Model::erased([0; 64]);
        f.cut_power_at(1);
        f.write(0, &[0; 8]).unwrap();
        assert_eq!(f.write(8, &[0; 16]), Err(ModelError::PowerCut));
        // 4 words: the first two programmed, the third half, the fourth untouched.
        assert_eq!(&f.bytes()[8..16], &[0; 8]);
        assert_eq!(&f.bytes()[16..20], &[0x0F; 4]);
        assert_eq!(&f.bytes()[20..24], &[0xFF; 4]);
        assert_eq!(f.erase(0, 32), Err(ModelError::PowerCut));
        assert_eq!(f.read(0, &mut [0; 4]), Err(ModelError::PowerCut));
        f.restore_power();
        assert_eq!(&f.bytes()[..8], &[0; 8], "the cut erase never ran");
    }

    #[test]
    fn a_power_cut_during_an_erase_leaves_half_the_sector() {
        let mut f = Model::erased([0; 64]);
        f.write(0, &[0; 32]).unwrap();
        f.cut_power_at(0);
        assert_eq!(f.erase(0, 32), Err(ModelError::PowerCut));
        assert!(f.bytes()[..16].iter().all(|b| *b == 0xFF));
        assert!(f.bytes()[16..32].iter().all(|b| *b == 0x00));
    }
}
