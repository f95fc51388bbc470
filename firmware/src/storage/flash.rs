//! A NOR-flash model for the settings store, with real erase/write semantics, that can lose
//! power at any operation in every shape a power cut leaves (for the sim and the tests).
//!
//! The model behaves as the STM32F4's flash does where the store can tell: an erase sets a whole
//! sector to `0xFF`; a write can only clear bits (`stored & data`, so writing a word twice is
//! allowed, as on the F4, which has no ECC); writes and reads outside the area, and writes not
//! aligned to `WRITE` bytes, are errors. Power cuts: [`NorFlashModel::cut_power`] makes the
//! n-th write or erase from now stop part-way, leaving what [`Cut`] describes, and every
//! operation after it fail, until [`NorFlashModel::restore_power`]. A write is cut in the
//! order the F4 programs (word after word) with the word being written at the cut holding
//! only some of its bits; an erase is cut in no fixed order (a sector erase is not specified to
//! progress from its start: its first part, its last part, all but its first words, or a
//! scattered choice of words and bits may be left as they were).

use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

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

/// What a power cut leaves of the operation it interrupts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// Half of it in order: a write programs the first half of its words and, of the next
    /// one, only the bits of every other nibble; an erase sets the first half of the sector to
    /// `0xFF` and leaves the rest as it was (its tail still programmed).
    Partial,
    /// None of it: the power fails just before the operation starts (after the one before it
    /// completed).
    Before,
    /// A write as [`Cut::Partial`]; an erase sets the *second* half of the sector and leaves
    /// the first as it was.
    PartialTail,
    /// Nearly all of it: a write programs every word but its last, and of the last only some
    /// bits (bits flipped in the word being written); an erase sets everything but the first
    /// `2 × max(16, WRITE)` bytes (a sector header there left standing over an erased sector).
    NearlyAll,
    /// A scattered part, from a seed: a write programs a prefix of pseudo-random length in
    /// order and random bits of the word after it; an erase leaves each word erased, as it
    /// was, or with random bits set.
    Scattered(u32),
}

impl Cut {
    /// Every shape, with `seeds` scattered ones (seeds 1..=seeds): what the sweeps cut with.
    pub fn shapes(seeds: u32) -> impl Iterator<Item = Cut> {
        [Cut::Before, Cut::Partial, Cut::PartialTail, Cut::NearlyAll]
            .into_iter()
            .chain((1..=seeds).map(Cut::Scattered))
    }
}

/// xorshift32 (the model's only source of "random" patterns: fixed by the seed).
fn next_rand(state: &mut u32) -> u32 {
    let mut x = (*state).max(1);
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    x
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
            let kind = self.cut_kind;
            let mem = &mut self.mem.as_mut()[sector..sector + ERASE];
            if cut {
                cut_erase(mem, kind, WRITE);
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
        let kind = self.cut_kind;
        let mem = &mut self.mem.as_mut()[r];
        if cut {
            cut_write(mem, bytes, kind, WRITE);
            return Err(ModelError::PowerCut);
        }
        for (m, b) in mem.iter_mut().zip(bytes) {
            *m &= *b;
        }
        Ok(())
    }
}

/// What a write of `bytes` over `mem` cut as `kind` leaves (programmed in order, word by word;
/// the word being written at the cut holds only some of its bits).
fn cut_write(mem: &mut [u8], bytes: &[u8], kind: Cut, word: usize) {
    let words = bytes.len() / word;
    let mut rand = 0x9E37_79B9;
    // Whole words programmed; then the next one with the bits of `unset` left unprogrammed.
    let whole = match kind {
        Cut::Before => return,
        Cut::Partial | Cut::PartialTail => words / 2,
        Cut::NearlyAll => words.saturating_sub(1),
        Cut::Scattered(seed) => {
            rand ^= seed;
            next_rand(&mut rand) as usize % (words + 1)
        }
    };
    let done = whole * word;
    for (m, b) in mem.iter_mut().zip(bytes).take(done) {
        *m &= *b;
    }
    let next = (done + word).min(bytes.len());
    for (m, b) in mem.iter_mut().zip(bytes).take(next).skip(done) {
        let unset = match kind {
            Cut::NearlyAll => 0xA5,
            Cut::Scattered(_) => next_rand(&mut rand) as u8,
            _ => 0x0F,
        };
        *m &= *b | unset;
    }
}

/// What an erase of the sector `mem` cut as `kind` leaves (no fixed order).
fn cut_erase(mem: &mut [u8], kind: Cut, word: usize) {
    let len = mem.len();
    match kind {
        Cut::Before => {}
        Cut::Partial => mem[..len / 2].fill(0xFF),
        Cut::PartialTail => mem[len / 2..].fill(0xFF),
        Cut::NearlyAll => {
            let kept = (2 * word.max(16)).min(len);
            mem[kept..].fill(0xFF);
        }
        Cut::Scattered(seed) => {
            let mut rand = 0x85EB_CA6B ^ seed;
            for w in mem.chunks_mut(word) {
                match next_rand(&mut rand) % 3 {
                    0 => w.fill(0xFF),
                    1 => {}
                    _ => w.iter_mut().for_each(|b| *b |= next_rand(&mut rand) as u8),
                }
            }
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
