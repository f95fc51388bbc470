//! The parameter words of one command: scanned once from the line, then read by letter with
//! the letter set, flags and number ranges checked.

use super::lex::{is_space, paren};
use super::number::{self, Num};
use super::{err, AxisFlags, AxisWords, ParseError, ParseErrorKind};

/// Most distinct parameter letters one line may carry (known commands take at most 8; more is
/// an [`ParseErrorKind::UnexpectedLetter`], or text for an unknown command).
pub(super) const MAX_WORDS: usize = 16;

/// A parameter word: letter index 0..26 and its number, if any.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Word {
    pub(super) num: Option<Num>,
    pub(super) letter: u8,
    pub(super) at: u16,
}

/// The parameter words of one command.
pub(super) struct Words<'a> {
    pub(super) line: &'a [u8],
    pub(super) mask: u32,
    /// Index into `words` of each letter present (valid where `mask` has the bit).
    pub(super) slot: [u8; 26],
    /// Filled lazily (no per-line initialisation of every slot).
    pub(super) words: heapless::Vec<Word, MAX_WORDS>,
    /// Position of the first repeated letter, reported by `check` after the per-word errors.
    pub(super) dup: Option<usize>,
    /// Letters taken and ignored ([`Words::ignore_all`]), for [`super::Line::ignored`].
    pub(super) ignored: core::cell::Cell<u32>,
}

impl<'a> Words<'a> {
    pub(super) fn new(line: &'a [u8]) -> Self {
        Words {
            line,
            mask: 0,
            slot: [0; 26],
            words: heapless::Vec::new(),
            dup: None,
            ignored: core::cell::Cell::new(0),
        }
    }
}

/// Bit of a letter in a letter mask.
pub(super) const fn bit(c: u8) -> u32 {
    1 << (c - b'A')
}

/// Letter mask of a set of upper-case letters.
const fn mask(s: &[u8]) -> u32 {
    let mut m = 0;
    let mut i = 0;
    while i < s.len() {
        m |= bit(s[i]);
        i += 1;
    }
    m
}

impl<'a> Words<'a> {
    pub(super) fn find(&self, c: u8) -> Option<&Word> {
        if self.mask & bit(c) == 0 {
            return None;
        }
        let i = self.slot.get(usize::from(c - b'A'))?;
        self.words.get(usize::from(*i))
    }

    /// Check the letters: only `allowed`; letters outside `flags` need a number.
    pub(super) fn check(&self, allowed: &[u8], flags: &[u8]) -> Result<(), ParseError> {
        let allowed_m = mask(allowed);
        let flags_m = mask(flags);
        for w in self.words.iter() {
            let b = 1u32 << w.letter;
            if allowed_m & b == 0 {
                return Err(err(ParseErrorKind::UnexpectedLetter, usize::from(w.at)));
            }
            if w.num.is_none() && flags_m & b == 0 {
                return Err(err(ParseErrorKind::MissingNumber, usize::from(w.at) + 1));
            }
        }
        match self.dup {
            Some(at) => Err(err(ParseErrorKind::DuplicateLetter, at)),
            None => Ok(()),
        }
    }

    /// For a command whose Marlin handler reads no parameter (M400, G90, ...): Marlin's parser
    /// takes any words and the handler never looks at them, so every word is taken (numbers or
    /// not, repeated or not) and reported as ignored rather than refused.
    pub(super) fn ignore_all(&self) -> Result<(), ParseError> {
        self.ignored.set(self.mask);
        Ok(())
    }

    pub(super) fn f32(&self, c: u8) -> Result<Option<f32>, ParseError> {
        match self.find(c) {
            Some(Word {
                num: Some(n), at, ..
            }) => n
                .to_f32(self.line)
                .map(Some)
                .map_err(|k| err(k, usize::from(*at) + 1)),
            _ => Ok(None),
        }
    }

    pub(super) fn u32(&self, c: u8) -> Result<Option<u32>, ParseError> {
        match self.find(c) {
            Some(Word {
                num: Some(n), at, ..
            }) => n
                .to_u32()
                .map(Some)
                .map_err(|k| err(k, usize::from(*at) + 1)),
            _ => Ok(None),
        }
    }

    pub(super) fn u8(&self, c: u8) -> Result<Option<u8>, ParseError> {
        match self.find(c) {
            Some(Word {
                num: Some(n), at, ..
            }) => n
                .to_u8()
                .map(Some)
                .map_err(|k| err(k, usize::from(*at) + 1)),
            _ => Ok(None),
        }
    }

    pub(super) fn i32(&self, c: u8) -> Result<Option<i32>, ParseError> {
        match self.find(c) {
            Some(Word {
                num: Some(n), at, ..
            }) => {
                let at = usize::from(*at) + 1;
                let v = n.to_i64().map_err(|k| err(k, at))?;
                i32::try_from(v)
                    .map(Some)
                    .map_err(|_| err(ParseErrorKind::OutOfRange, at))
            }
            _ => Ok(None),
        }
    }

    /// A refusal of word `c`'s value, at the column of its number (of the letter when it has
    /// none): `M569 S2 X` blames column 7, not column 1.
    pub(super) fn refuse(&self, c: u8, kind: ParseErrorKind) -> ParseError {
        let at = self
            .find(c)
            .map_or(0, |w| usize::from(w.at) + usize::from(w.num.is_some()));
        err(kind, at)
    }

    /// A refusal of the `i`-th word (in the order written), at its letter.
    pub(super) fn refuse_nth(&self, i: usize, kind: ParseErrorKind) -> ParseError {
        err(kind, self.words.get(i).map_or(0, |w| usize::from(w.at)))
    }

    pub(super) fn has(&self, c: u8) -> bool {
        self.mask & bit(c) != 0
    }

    pub(super) fn axes(&self) -> Result<AxisWords, ParseError> {
        Ok(AxisWords([
            self.f32(b'X')?,
            self.f32(b'Y')?,
            self.f32(b'Z')?,
            self.f32(b'E')?,
        ]))
    }

    pub(super) fn flags(&self) -> AxisFlags {
        AxisFlags([
            self.has(b'X'),
            self.has(b'Y'),
            self.has(b'Z'),
            self.has(b'E'),
        ])
    }

    /// A flag that must be 0/1 when it has a number (`S1`, `U1`); absent = false.
    pub(super) fn bool01(&self, c: u8) -> Result<bool, ParseError> {
        match self.find(c) {
            None => Ok(false),
            Some(Word { num: None, .. }) => Ok(true),
            Some(Word {
                num: Some(n), at, ..
            }) => match n.to_u32() {
                Ok(0) => Ok(false),
                Ok(1) => Ok(true),
                _ => Err(err(ParseErrorKind::BadValue, usize::from(*at) + 1)),
            },
        }
    }
}

/// Scan parameter words from `i` to the end of `code`.
pub(super) fn scan_words<'a>(
    code: &'a [u8],
    mut i: usize,
    paren_comment: &mut Option<&'a [u8]>,
    w: &mut Words<'a>,
) -> Result<Option<usize>, ParseError> {
    while let Some(&c) = code.get(i) {
        if c == b';' {
            return Ok(Some(i));
        }
        if is_space(c) || c == b'\r' || c == b'\n' {
            i += 1;
            continue;
        }
        if c == b'(' {
            let (text, next) = paren(code, i)?;
            *paren_comment = paren_comment.or(Some(text));
            i = next;
            continue;
        }
        if !c.is_ascii_alphabetic() {
            return Err(err(ParseErrorKind::BadByte, i));
        }
        let up = c.to_ascii_uppercase();
        let b = bit(up);
        let dup = w.mask & b != 0;
        if dup {
            w.dup = w.dup.or(Some(i));
        }
        let num = number::lex(code, i + 1).map_err(|k| err(k, i + 1))?;
        let (num, next) = match num {
            Some((n, next)) => (Some(n), next),
            None => (None, i + 1),
        };
        // A number must be followed by a separator or the next letter.
        if let Some(&after) = code.get(next) {
            if !(after.is_ascii_alphabetic()
                || is_space(after)
                || after == b'('
                || after == b';'
                || after == b'\r'
                || after == b'\n')
            {
                return Err(err(ParseErrorKind::BadByte, next));
            }
        }
        if !dup {
            let idx = w.words.len() as u8;
            w.words
                .push(Word {
                    letter: up - b'A',
                    num,
                    at: i.min(usize::from(u16::MAX)) as u16,
                })
                .map_err(|_| err(ParseErrorKind::UnexpectedLetter, i))?;
            if let Some(s) = w.slot.get_mut(usize::from(up - b'A')) {
                *s = idx;
            }
        }
        w.mask |= b;
        i = next;
    }
    Ok(None)
}
