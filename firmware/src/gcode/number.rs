//! Decimal numbers as G-code writes them: `[+-]? digits [. digits]` or `[+-]? . digits`.
//!
//! There is no exponent (in G-code `X1E5` means X=1, E=5), no `nan`, no `inf`. A number is lexed
//! once into an exact decimal (mantissa and count of fractional digits) and converted on demand:
//! to `f32` with correct rounding (an exact fast path for the usual short numbers, an exact
//! integer division otherwise: core's parser would link its 10 KiB power-of-five table and
//! big-decimal code into the image) or to an integer (exact, or an error if it has a fraction).

use super::ParseErrorKind;

/// Largest magnitude accepted for a decimal value (mm, mm/min, °C, ms, ...): ten kilometres of
/// filament in absolute E mode still fits, `1e30`-style garbage does not.
pub const MAX_ABS_VALUE: f32 = 1.0e7;

/// Smallest non-zero magnitude accepted (anything smaller is no printer quantity, and this
/// bound keeps every value's shortest decimal short enough for the parser: the emitter's output
/// always parses back).
pub const MIN_ABS_VALUE: f32 = 1.0e-12;

/// Most significant digits a number may have (exactly representable in the u64 mantissa).
pub const MAX_SIG_DIGITS: u8 = 19;

/// Longest number text accepted, sign and point included.
pub const MAX_NUMBER_LEN: usize = 32;

/// Powers of ten that are exact in `f32` (10^0 ..= 10^10).
const POW10_F32: [f32; 11] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];

/// Powers of ten that fit in `u64` (10^0 ..= 10^19).
const POW10_U64: [u64; 20] = {
    let mut t = [1u64; 20];
    let mut i = 1;
    while i < 20 {
        t[i] = t[i - 1] * 10;
        i += 1;
    }
    t
};

/// An exact decimal as written in the line: `(-1)^neg * mant / 10^scale`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Num {
    /// Digits without the point.
    pub mant: u64,
    /// Number of digits after the point.
    pub scale: u8,
    /// A leading `-`.
    pub neg: bool,
    /// Start of the number text in the line (for the slow conversion path).
    pub start: u16,
    /// End (exclusive) of the number text in the line.
    pub end: u16,
}

/// Lex a number starting at `pos` in `line`. Returns the number and the position after it, or
/// `Ok(None)` if no number starts there (no sign, digit or point).
pub(crate) fn lex(line: &[u8], pos: usize) -> Result<Option<(Num, usize)>, ParseErrorKind> {
    let rest = line.get(pos..).unwrap_or(&[]);
    let (neg, body) = match rest.first() {
        Some(b'-') => (true, rest.get(1..).unwrap_or(&[])),
        Some(b'+') => (false, rest.get(1..).unwrap_or(&[])),
        Some(c) if c.is_ascii_digit() || *c == b'.' => (false, rest),
        _ => return Ok(None),
    };
    let sign_len = rest.len() - body.len();
    let mut mant: u64 = 0;
    let mut k = 0usize;
    // Integer digits, then an optional point and fraction digits. Wrapping arithmetic: the
    // result is exact whenever there are at most 19 significant digits, checked below.
    while let Some(d) = body
        .get(k)
        .map(|c| c.wrapping_sub(b'0'))
        .filter(|d| *d <= 9)
    {
        mant = mant.wrapping_mul(10).wrapping_add(u64::from(d));
        k += 1;
    }
    let int_digits = k;
    let mut scale = 0usize;
    if body.get(k) == Some(&b'.') {
        k += 1;
        let fs = k;
        while let Some(d) = body
            .get(k)
            .map(|c| c.wrapping_sub(b'0'))
            .filter(|d| *d <= 9)
        {
            mant = mant.wrapping_mul(10).wrapping_add(u64::from(d));
            k += 1;
        }
        scale = k - fs;
    }
    let digits = int_digits + scale;
    if digits == 0 {
        return Err(ParseErrorKind::MissingNumber);
    }
    if digits > usize::from(MAX_SIG_DIGITS) {
        // Leading zeros do not count.
        let zeros = body
            .get(..k)
            .unwrap_or(&[])
            .iter()
            .take_while(|&&c| c == b'0' || c == b'.')
            .filter(|&&c| c == b'0')
            .count();
        if digits - zeros > usize::from(MAX_SIG_DIGITS) {
            return Err(ParseErrorKind::TooManyDigits);
        }
    }
    let len = sign_len + k;
    if len > MAX_NUMBER_LEN {
        return Err(ParseErrorKind::NumberTooLong);
    }
    let end = pos + len;
    // `len <= MAX_NUMBER_LEN`, so scale fits in u8; positions saturate for the long lines only
    // host tools parse.
    let num = Num {
        mant,
        scale: scale as u8,
        neg,
        start: pos.min(usize::from(u16::MAX)) as u16,
        end: end.min(usize::from(u16::MAX)) as u16,
    };
    Ok(Some((num, end)))
}

impl Num {
    /// The value as `f32`, correctly rounded, within ±[`MAX_ABS_VALUE`].
    pub fn to_f32(self, _line: &[u8]) -> Result<f32, ParseErrorKind> {
        let mag = if self.mant <= (1 << 24) && usize::from(self.scale) < POW10_F32.len() {
            // Both operands exact in f32, so the single division rounds correctly.
            let p = POW10_F32
                .get(usize::from(self.scale))
                .copied()
                .unwrap_or(1.0);
            self.mant as f32 / p
        } else {
            exact_f32(self.mant, self.scale)
        };
        if !mag.is_finite() || mag > MAX_ABS_VALUE || (mag != 0.0 && mag < MIN_ABS_VALUE) {
            return Err(ParseErrorKind::OutOfRange);
        }
        Ok(if self.neg { -mag } else { mag })
    }

    /// The value as an exact integer; a fractional part that is not zero is an error.
    pub fn to_i64(self) -> Result<i64, ParseErrorKind> {
        let whole = if self.scale == 0 {
            self.mant
        } else {
            let Some(&p) = POW10_U64.get(usize::from(self.scale)) else {
                // More than 19 fractional digits: only an all-zero mantissa is whole.
                return if self.mant == 0 {
                    Ok(0)
                } else {
                    Err(ParseErrorKind::NotWhole)
                };
            };
            if !self.mant.is_multiple_of(p) {
                return Err(ParseErrorKind::NotWhole);
            }
            self.mant / p
        };
        let v = i64::try_from(whole).map_err(|_| ParseErrorKind::OutOfRange)?;
        Ok(if self.neg { -v } else { v })
    }

    /// The value as a non-negative `u32`.
    pub fn to_u32(self) -> Result<u32, ParseErrorKind> {
        let v = self.to_i64()?;
        if v < 0 {
            return Err(ParseErrorKind::Negative);
        }
        u32::try_from(v).map_err(|_| ParseErrorKind::OutOfRange)
    }

    /// The value as a small non-negative index (tool, fan, heater).
    pub fn to_u8(self) -> Result<u8, ParseErrorKind> {
        u8::try_from(self.to_u32()?).map_err(|_| ParseErrorKind::OutOfRange)
    }
}

/// A whole text that is one decimal number (as in a G-code word), as `f32`: for numbers in
/// comments (the layer detector's `;Z:0.3`), so nothing else parses floats (see the module
/// documentation). None for anything else (exponents, `inf`, trailing text) or out of range.
pub(crate) fn decimal(text: &[u8]) -> Option<f32> {
    match lex(text, 0) {
        Ok(Some((n, end))) if end == text.len() => n.to_f32(text).ok(),
        _ => None,
    }
}

/// The largest `scale` [`lex`] can give: a number of at most [`MAX_NUMBER_LEN`] bytes has at
/// most that many less one (the point) fractional digits. [`exact_f32`] relies on it (`r << 24`
/// fits in `u128` only while `10^scale < 2^104`), so a longer number limit fails to compile.
const MAX_SCALE: u8 = (MAX_NUMBER_LEN - 1) as u8;
const _: () = assert!(MAX_SCALE <= 31);

/// `mant / 10^scale` as `f32`, correctly rounded (to nearest, ties to even), by integer
/// division: the quotient's leading bits and whether anything was left over decide the
/// rounding. Exact for every number [`lex`] gives (`mant < 10^19`, `scale <= 31`, so
/// `10^scale < 2^104` and every value is a normal `f32`).
fn exact_f32(mant: u64, scale: u8) -> f32 {
    if mant == 0 {
        return 0.0;
    }
    let d = 10u128.pow(u32::from(scale.min(MAX_SCALE)));
    // value = n / d * 2^e, with n in [2^127, 2^128).
    let t = mant.leading_zeros();
    let n = u128::from(mant << t) << 64;
    let (mut q, mut r) = (n / d, n % d);
    let mut e = -(64 + t as i32);
    if q < 1 << 40 {
        // A large divisor (d > 2^87, so r < d < 2^104 and r << 24 fits): 24 more bits.
        let n2 = r << 24;
        q = (q << 24) | (n2 / d);
        r = n2 % d;
        e -= 24;
    }
    // q >= 2^40: keep its 24 leading bits, round on the rest and the remainder.
    let shift = (128 - q.leading_zeros()) - 24;
    let mut m = (q >> shift) as u32;
    let rest = q & ((1u128 << shift) - 1);
    let half = 1u128 << (shift - 1);
    if rest > half || (rest == half && (r != 0 || m & 1 == 1)) {
        m += 1;
    }
    let mut exp = e + shift as i32;
    if m == 1 << 24 {
        m >>= 1;
        exp += 1;
    }
    // m in [2^23, 2^24): the value is m * 2^exp; a normal f32's biased exponent is exp + 150.
    match u32::try_from(exp + 150) {
        Ok(b) if (1..255).contains(&b) => f32::from_bits((b << 23) | (m & 0x7F_FFFF)),
        _ => f32::INFINITY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn f(s: &str) -> Result<f32, ParseErrorKind> {
        let b = s.as_bytes();
        match lex(b, 0)? {
            Some((n, end)) if end == b.len() => n.to_f32(b),
            _ => Err(ParseErrorKind::BadNumber),
        }
    }

    #[test]
    fn forms() {
        assert_eq!(f("10"), Ok(10.0));
        assert_eq!(f("-1.5"), Ok(-1.5));
        assert_eq!(f("+.5"), Ok(0.5));
        assert_eq!(f(".03321"), Ok(0.03321));
        assert_eq!(f("7."), Ok(7.0));
        assert_eq!(f("0000000000000000000000001.25"), Ok(1.25));
        assert_eq!(f("-"), Err(ParseErrorKind::MissingNumber));
        assert_eq!(f("."), Err(ParseErrorKind::MissingNumber));
        assert_eq!(f("10000001"), Err(ParseErrorKind::OutOfRange));
        assert_eq!(f("-.0000000000001"), Err(ParseErrorKind::OutOfRange));
        assert_eq!(f("-.000000000000000000000000000000"), Ok(-0.0));
        assert_eq!(
            f("1000000000000000000000000000000"),
            Err(ParseErrorKind::TooManyDigits)
        );
    }

    #[test]
    fn integers() {
        let b = b"12.000";
        let (n, _) = lex(b, 0).unwrap().unwrap();
        assert_eq!(n.to_u32(), Ok(12));
        let b = b"12.5";
        let (n, _) = lex(b, 0).unwrap().unwrap();
        assert_eq!(n.to_u32(), Err(ParseErrorKind::NotWhole));
        let b = b"-3";
        let (n, _) = lex(b, 0).unwrap().unwrap();
        assert_eq!(n.to_u32(), Err(ParseErrorKind::Negative));
        let b = b"4294967296";
        let (n, _) = lex(b, 0).unwrap().unwrap();
        assert_eq!(n.to_u32(), Err(ParseErrorKind::OutOfRange));
    }

    proptest! {
        /// The fast path and the fallback agree with core's correctly rounded parser on every
        /// decimal G-code is likely to contain (and many it is not).
        #[test]
        fn agrees_with_core(int in 0u64..10_000_000, frac in 0u64..100_000_000, fd in 0usize..9, neg: bool) {
            let mut s = heapless::String::<40>::new();
            use core::fmt::Write;
            let fd_digits = if fd == 0 { 0 } else { frac % 10u64.pow(fd as u32) };
            if fd == 0 {
                write!(s, "{}{}", if neg { "-" } else { "" }, int).unwrap();
            } else {
                write!(s, "{}{}.{:0w$}", if neg { "-" } else { "" }, int, fd_digits, w = fd).unwrap();
            }
            let want: f32 = s.parse().unwrap();
            prop_assert_eq!(f(&s).map(f32::to_bits), Ok(want.to_bits()), "{}", s);
        }

        /// The integer-division path against core's parser over its whole domain: up to 19
        /// significant digits, up to 31 fractional ones.
        #[test]
        fn exact_path_agrees_with_core(mant in 0u64..10_000_000_000_000_000_000, digits in 1u32..20, scale in 0u8..32) {
            let mant = mant % 10u64.pow(digits).max(1);
            let mut s = heapless::String::<64>::new();
            use core::fmt::Write;
            let text = heapless::String::<20>::try_from(mant.to_string().as_str()).unwrap();
            let scale_u = usize::from(scale);
            if scale_u == 0 {
                write!(s, "{text}").unwrap();
            } else if text.len() > scale_u {
                let (i, f) = text.split_at(text.len() - scale_u);
                write!(s, "{i}.{f}").unwrap();
            } else {
                write!(s, "0.{:0>w$}", text.as_str(), w = scale_u).unwrap();
            }
            let want: f32 = s.parse().unwrap();
            prop_assert_eq!(exact_f32(mant, scale).to_bits(), want.to_bits(), "{}", s);
        }

        /// Shortest round-trip text of any in-range f32 parses back to the same bits.
        #[test]
        fn display_round_trips(v in -1.0e7f32..1.0e7, tiny in 1.0e-12f32..1.0e-6) {
            let mut s = heapless::String::<64>::new();
            use core::fmt::Write;
            write!(s, "{}", v).unwrap();
            prop_assert_eq!(f(&s).map(f32::to_bits), Ok(v.to_bits()), "{}", s);
            let mut s = heapless::String::<64>::new();
            write!(s, "-{}", tiny).unwrap();
            prop_assert!(s.len() <= MAX_NUMBER_LEN);
            prop_assert_eq!(f(&s).map(f32::to_bits), Ok((-tiny).to_bits()), "{}", s);
        }
    }
}
