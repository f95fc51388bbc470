//! Decimal numbers as G-code writes them: `[+-]? digits [. digits] [exponent]` or
//! `[+-]? . digits [exponent]`, the exponent `e`/`E` with an optional sign and at least one digit.
//!
//! An exponent is part of the number, as C's `strtof` (Marlin's reader) takes it: `X1e-05` (what
//! Python's `str()` and C's `%g` write for a small value) is X = 0.00001, never X = 1 plus an
//! `E-05` word; a value that ends up out of range is refused, not cut. An `e`/`E` that is not
//! followed by a digit (with an optional sign) is the next word's letter, as before (`G1 X1 E2`,
//! `G1X1E`). No `nan`, no `inf`, no hexadecimal. A number is lexed once into an exact decimal
//! (mantissa and power of ten) and converted on demand: to `f32` with correct rounding (an exact
//! fast path for the usual short numbers, an exact integer division otherwise: core's parser
//! would link its 10 KiB power-of-five table and big-decimal code into the image) or to an
//! integer (exact, or an error if it has a fraction).

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

/// Largest exponent magnitude kept while reading one (more digits saturate: the value is out
/// of range long before).
const MAX_EXPONENT: i32 = 9999;

/// An exact decimal as written in the line: `(-1)^neg * mant / 10^scale`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Num {
    /// Digits without the point.
    pub mant: u64,
    /// Power of ten the mantissa is divided by: the digits after the point less the exponent
    /// (negative: multiplied, `1e5`).
    pub scale: i16,
    /// A leading `-`.
    pub neg: bool,
    /// Start of the number text in the line (for the slow conversion path).
    pub start: u16,
    /// End (exclusive) of the number text in the line.
    pub end: u16,
}

/// The digits at `body[k..]`, accumulated into `acc` by `step`; returns the end.
fn digits_from(body: &[u8], mut k: usize, mut step: impl FnMut(u8)) -> usize {
    while let Some(d) = body
        .get(k)
        .map(|c| c.wrapping_sub(b'0'))
        .filter(|d| *d <= 9)
    {
        step(d);
        k += 1;
    }
    k
}

/// An exponent at `body[k..]` (`e`/`E`, an optional sign, at least one digit): its value and
/// the position after it, or `None` when none starts there (the `e` is then a letter).
fn exponent(body: &[u8], k: usize) -> Option<(i32, usize)> {
    if !matches!(body.get(k), Some(b'e' | b'E')) {
        return None;
    }
    let (neg, first) = match body.get(k + 1) {
        Some(b'-') => (true, k + 2),
        Some(b'+') => (false, k + 2),
        _ => (false, k + 1),
    };
    if !body.get(first).is_some_and(u8::is_ascii_digit) {
        return None;
    }
    let mut e: i32 = 0;
    let end = digits_from(body, first, |d| {
        e = (e * 10 + i32::from(d)).min(MAX_EXPONENT);
    });
    Some((if neg { -e } else { e }, end))
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
    // Integer digits, then an optional point and fraction digits. Wrapping arithmetic: the
    // result is exact whenever there are at most 19 significant digits, checked below.
    let mut push = |d: u8| mant = mant.wrapping_mul(10).wrapping_add(u64::from(d));
    let mut k = digits_from(body, 0, &mut push);
    let int_digits = k;
    let mut frac = 0usize;
    if body.get(k) == Some(&b'.') {
        let fs = k + 1;
        k = digits_from(body, fs, &mut push);
        frac = k - fs;
    }
    let digits = int_digits + frac;
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
    let mut exp = 0;
    if let Some((e, end)) = exponent(body, k) {
        exp = e;
        k = end;
        // `1e5.5`: no reading of it is the file's number.
        if body.get(k) == Some(&b'.') {
            return Err(ParseErrorKind::BadNumber);
        }
    }
    let len = sign_len + k;
    if len > MAX_NUMBER_LEN {
        return Err(ParseErrorKind::NumberTooLong);
    }
    let end = pos + len;
    // `frac < MAX_NUMBER_LEN` and `|exp| <= MAX_EXPONENT`, so the scale fits in i16; positions
    // saturate for the long lines only host tools parse.
    let scale = (frac as i32 - exp) as i16;
    let num = Num {
        mant,
        scale,
        neg,
        start: pos.min(usize::from(u16::MAX)) as u16,
        end: end.min(usize::from(u16::MAX)) as u16,
    };
    Ok(Some((num, end)))
}

impl Num {
    /// The value as `mant / 10^scale` with `scale` in `0..=`[`MAX_SCALE`]: a scale below zero
    /// (an exponent that scales up) is multiplied in — exactly, or out of range — and a non-zero
    /// value with a larger scale is below [`MIN_ABS_VALUE`] (the mantissa has at most 19
    /// digits, so it is under `10^19 / 10^32`).
    fn normal(self) -> Result<(u64, u8), ParseErrorKind> {
        if self.mant == 0 {
            return Ok((0, 0));
        }
        if self.scale < 0 {
            let m = POW10_U64
                .get(usize::from(self.scale.unsigned_abs()))
                .and_then(|p| self.mant.checked_mul(*p))
                .ok_or(ParseErrorKind::OutOfRange)?;
            return Ok((m, 0));
        }
        match u8::try_from(self.scale) {
            Ok(s) if s <= MAX_SCALE => Ok((self.mant, s)),
            _ => Err(ParseErrorKind::OutOfRange),
        }
    }

    /// The value as `f32`, correctly rounded, within ±[`MAX_ABS_VALUE`].
    pub fn to_f32(self, _line: &[u8]) -> Result<f32, ParseErrorKind> {
        let (mant, scale) = self.normal()?;
        let mag = if mant <= (1 << 24) && usize::from(scale) < POW10_F32.len() {
            // Both operands exact in f32, so the single division rounds correctly.
            let p = POW10_F32.get(usize::from(scale)).copied().unwrap_or(1.0);
            mant as f32 / p
        } else {
            exact_f32(mant, scale)
        };
        if !mag.is_finite() || mag > MAX_ABS_VALUE || (mag != 0.0 && mag < MIN_ABS_VALUE) {
            return Err(ParseErrorKind::OutOfRange);
        }
        Ok(if self.neg { -mag } else { mag })
    }

    /// The value as an exact integer; a fractional part that is not zero is an error.
    pub fn to_i64(self) -> Result<i64, ParseErrorKind> {
        let whole = if self.scale <= 0 {
            self.normal()?.0
        } else {
            let Some(&p) = POW10_U64.get(usize::from(self.scale.unsigned_abs())) else {
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
/// comments (the layer detector's `;Z:0.3`, `;Z:1e-3`), so nothing else parses floats (see the
/// module documentation). None for anything else (`inf`, trailing text) or out of range.
pub(crate) fn decimal(text: &[u8]) -> Option<f32> {
    match lex(text, 0) {
        Ok(Some((n, end))) if end == text.len() => n.to_f32(text).ok(),
        _ => None,
    }
}

/// The largest scale converted ([`Num::normal`]; beyond it every non-zero value is below
/// [`MIN_ABS_VALUE`]). [`exact_f32`] relies on it (`r << 24` fits in `u128` only while
/// `10^scale < 2^104`).
const MAX_SCALE: u8 = 31;
const _: () = assert!(10u128.pow(MAX_SCALE as u32) < 1 << 104);

/// `mant / 10^scale` as `f32`, correctly rounded (to nearest, ties to even), by integer
/// division: the quotient's leading bits and whether anything was left over decide the
/// rounding. Exact for every number [`Num::normal`] gives (`mant < 10^19` or a product
/// that fits in `u64`, `scale <= 31`, so
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
    fn exponents_are_part_of_the_number() {
        assert_eq!(f("1e-05"), Ok(1e-5));
        assert_eq!(f("1E-05"), Ok(1e-5));
        assert_eq!(f("-2.5e+03"), Ok(-2500.0));
        assert_eq!(f(".5e1"), Ok(5.0));
        assert_eq!(f("7.e2"), Ok(700.0));
        assert_eq!(f("0e99999999"), Ok(0.0));
        assert_eq!(f("1e7"), Ok(1e7));
        // Out of range either way: refused, never cut.
        assert_eq!(f("1e39"), Err(ParseErrorKind::OutOfRange));
        assert_eq!(f("1e9"), Err(ParseErrorKind::OutOfRange));
        assert_eq!(f("1e-13"), Err(ParseErrorKind::OutOfRange));
        assert_eq!(f("1e-99999"), Err(ParseErrorKind::OutOfRange));
        assert_eq!(f("1e99999"), Err(ParseErrorKind::OutOfRange));
        assert_eq!(f("1e5.5"), Err(ParseErrorKind::BadNumber));
        // Not an exponent: the `e` is the next letter.
        for (text, end) in [("1e", 1), ("1e-", 1), ("1E+X", 1), ("1EX", 1)] {
            let (n, at) = lex(text.as_bytes(), 0).unwrap().unwrap();
            assert_eq!((n.to_f32(b"").unwrap(), at), (1.0, end), "{text}");
        }
        let (n, _) = lex(b"2e3", 0).unwrap().unwrap();
        assert_eq!(n.to_u32(), Ok(2000));
        let (n, _) = lex(b"25e-1", 0).unwrap().unwrap();
        assert_eq!(n.to_u32(), Err(ParseErrorKind::NotWhole));
        let (n, _) = lex(b"1e-40", 0).unwrap().unwrap();
        assert_eq!(n.to_u32(), Err(ParseErrorKind::NotWhole));
        let (n, _) = lex(b"1e30", 0).unwrap().unwrap();
        assert_eq!(n.to_u32(), Err(ParseErrorKind::OutOfRange));
        // The layer detector's comment numbers share the lexer.
        assert_eq!(decimal(b"1e-3"), Some(1e-3));
    }

    /// What Python 3's `repr`/`str` of a float writes (`float_repr_style` "short"): the
    /// shortest digits that read back, exponent form below 1e-4 and from 1e16, the exponent
    /// with a sign and at least two digits, `.0` after a whole number in fixed form.
    fn python_repr(x: f64) -> String {
        let (digits, exp) = sci_digits(&format!("{x:e}"));
        let neg = if x.is_sign_negative() { "-" } else { "" };
        if !(-4..16).contains(&exp) {
            return format!("{neg}{}e{}", point_after_first(&digits), exp_text(exp));
        }
        let fixed = fixed_from_digits(&digits, exp);
        let fixed = if fixed.contains('.') {
            fixed
        } else {
            fixed + ".0"
        };
        format!("{neg}{fixed}")
    }

    /// What C's `printf("%.<p>g")` writes (`%g` is p = 6; `%G` upper case): p significant
    /// digits, exponent form when the exponent X is below -4 or at least p, trailing zeros and
    /// a trailing point removed.
    fn c_g(x: f64, p: usize, upper: bool) -> String {
        let (digits, exp) = sci_digits(&format!("{:.*e}", p - 1, x.abs()));
        let digits = digits.trim_end_matches('0');
        let digits = if digits.is_empty() { "0" } else { digits };
        let neg = if x.is_sign_negative() { "-" } else { "" };
        let e = if upper { "E" } else { "e" };
        if exp < -4 || exp >= p as i32 {
            format!("{neg}{}{e}{}", point_after_first(digits), exp_text(exp))
        } else {
            format!("{neg}{}", fixed_from_digits(digits, exp))
        }
    }

    /// Rust's `{:e}` text (`1.2345e-7`) as its digits (`12345`) and decimal exponent.
    fn sci_digits(s: &str) -> (String, i32) {
        let s = s.trim_start_matches('-');
        let (m, e) = s.split_once('e').unwrap();
        (m.replace('.', ""), e.parse().unwrap())
    }

    fn point_after_first(digits: &str) -> String {
        match digits.len() {
            1 => digits.to_string(),
            _ => format!("{}.{}", &digits[..1], &digits[1..]),
        }
    }

    fn exp_text(exp: i32) -> String {
        format!("{}{:02}", if exp < 0 { '-' } else { '+' }, exp.abs())
    }

    /// `d.ddd × 10^exp` in fixed notation, no trailing zeros after a point.
    fn fixed_from_digits(digits: &str, exp: i32) -> String {
        if exp < 0 {
            let zeros = "0".repeat((-exp - 1) as usize);
            return format!("0.{zeros}{digits}");
        }
        let int_len = exp as usize + 1;
        if digits.len() <= int_len {
            format!("{digits}{}", "0".repeat(int_len - digits.len()))
        } else {
            format!("{}.{}", &digits[..int_len], &digits[int_len..])
        }
    }

    /// The formatters above against the real tools' output (Python 3.11: `repr(v)`, and its
    /// `%` formatting, which follows C's printf: `'%g' % v`, `'%G' % v`, `'%.17g' % v`).
    #[test]
    fn formatters_match_python_and_printf() {
        let table: [(f64, &str, &str, &str, &str); 15] = [
            (1e-05, "1e-05", "1e-05", "1E-05", "1.0000000000000001e-05"),
            (0.1, "0.1", "0.1", "0.1", "0.10000000000000001"),
            (
                2.5e-05,
                "2.5e-05",
                "2.5e-05",
                "2.5E-05",
                "2.5000000000000001e-05",
            ),
            (
                -3e-06,
                "-3e-06",
                "-3e-06",
                "-3E-06",
                "-3.0000000000000001e-06",
            ),
            (
                1.5e-07,
                "1.5e-07",
                "1.5e-07",
                "1.5E-07",
                "1.4999999999999999e-07",
            ),
            (
                123456789.0,
                "123456789.0",
                "1.23457e+08",
                "1.23457E+08",
                "123456789",
            ),
            (0.0001, "0.0001", "0.0001", "0.0001", "0.0001"),
            (
                0.00012345678901234,
                "0.00012345678901234",
                "0.000123457",
                "0.000123457",
                "0.00012345678901234001",
            ),
            (1e16, "1e+16", "1e+16", "1E+16", "10000000000000000"),
            (9999999.5, "9999999.5", "1e+07", "1E+07", "9999999.5"),
            (1e-12, "1e-12", "1e-12", "1E-12", "9.9999999999999998e-13"),
            (
                7.25e-10,
                "7.25e-10",
                "7.25e-10",
                "7.25E-10",
                "7.2499999999999998e-10",
            ),
            (200.0, "200.0", "200", "200", "200"),
            (1e39, "1e+39", "1e+39", "1E+39", "9.9999999999999994e+38"),
            (1e9, "1000000000.0", "1e+09", "1E+09", "1000000000"),
        ];
        for (v, repr, g, big_g, g17) in table {
            assert_eq!(python_repr(v), repr, "{v}");
            assert_eq!(c_g(v, 6, false), g, "{v}");
            assert_eq!(c_g(v, 6, true), big_g, "{v}");
            assert_eq!(c_g(v, 17, false), g17, "{v}");
        }
    }

    /// What a formatted value must read as: core's correctly rounded `f32`, or refused as out
    /// of range when that is beyond the accepted magnitudes.
    fn want(s: &str) -> Result<u32, ParseErrorKind> {
        let v: f32 = s.parse().unwrap();
        let m = v.abs();
        if m.is_finite() && (m == 0.0 || (MIN_ABS_VALUE..=MAX_ABS_VALUE).contains(&m)) {
            Ok(v.to_bits())
        } else {
            Err(ParseErrorKind::OutOfRange)
        }
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

        /// Floats as Python and C format them, exponents included, read as the one number the
        /// text means (core's `str::parse`), in a G1 line too: never an extra `E` word.
        #[test]
        fn formatted_floats_read_as_written(
            m in 1.0f64..10.0,
            e in -15i32..10,
            neg: bool,
            p in 1usize..18,
            style in 0u8..4,
        ) {
            let x = if neg { -m } else { m } * 10f64.powi(e);
            let text = match style {
                0 => python_repr(x),
                1 => c_g(x, 6, false),
                2 => c_g(x, 6, true),
                _ => c_g(x, p, false),
            };
            let w = want(&text);
            prop_assert_eq!(f(&text).map(f32::to_bits), w, "{}", text);
            let line = format!("G1 X{text} Y20");
            let parsed = crate::gcode::parse_line(line.as_bytes()).map(|l| l.command);
            match (w, parsed) {
                (Ok(bits), Ok(Some(crate::gcode::Command::Motion(crate::gcode::MotionCommand::Move { axes, .. })))) => {
                    prop_assert_eq!(axes.0[0].map(f32::to_bits), Some(bits), "{}", line);
                    prop_assert_eq!(axes.0[1], Some(20.0));
                    prop_assert_eq!(axes.0[3], None, "{}: an extra E word", line);
                }
                (Err(k), Err(e)) => {
                    prop_assert_eq!(e.kind, k);
                    prop_assert_eq!(e.at, 4, "{}: the error names X's number", line);
                }
                (w, p) => prop_assert!(false, "{}: want {:?}, got {:?}", line, w, p),
            }
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
