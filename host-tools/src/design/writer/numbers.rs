//! Fast decimal formatting of G-code numbers: rounding without libm, and fixed-point values
//! with trimmed trailing zeros written straight into the output buffer.

/// `v.round() as i64` (half away from zero, saturating, NaN → 0) without the libm call that
/// `f64::round` becomes on baseline x86-64: the cast truncates, and `v - trunc(v)` is exact.
#[inline]
pub fn round_i64(v: f64) -> i64 {
    let t = v as i64;
    let f = v - t as f64;
    if f >= 0.5 {
        t.saturating_add(1)
    } else if f <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Appends `v` with at most `decimals` decimals, trailing zeros trimmed ("1.5", "-0.25", "3").
pub fn push_fixed(buf: &mut Vec<u8>, v: f64, decimals: u32) {
    let scale = 10i64.pow(decimals);
    let n = round_i64(v * scale as f64);
    push_scaled(buf, n, decimals);
}

/// Two ASCII digits of every number 0..100.
const DIGITS2: &[u8; 200] = b"0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Writes the decimal digits of `v` right-aligned ending at `end` of `dst`; returns the
/// first index. `dst` must have room (20 digits at most).
#[inline]
fn digits_into(dst: &mut [u8], mut end: usize, mut v: u64) -> usize {
    while v >= 100 {
        let d = (v % 100) as usize * 2;
        v /= 100;
        end -= 2;
        dst[end] = DIGITS2[d];
        dst[end + 1] = DIGITS2[d + 1];
    }
    if v >= 10 {
        let d = v as usize * 2;
        end -= 2;
        dst[end] = DIGITS2[d];
        dst[end + 1] = DIGITS2[d + 1];
    } else {
        end -= 1;
        dst[end] = b'0' + v as u8;
    }
    end
}

/// Number of decimal digits of `v` (1 for 0).
#[inline]
fn digit_count(mut v: u64) -> usize {
    let mut n = 1;
    while v >= 100 {
        v /= 100;
        n += 2;
    }
    n + usize::from(v >= 10)
}

/// Opens `WIDTH` bytes at the end of `buf` (one constant-size store) for a number to be
/// written in place; the caller cuts it back to the number's length. Writing the digits
/// straight into the output avoids copying them from a stack buffer just written byte by
/// byte (a store-forwarding stall per number in profiles).
#[inline]
fn open_slot<const WIDTH: usize>(buf: &mut Vec<u8>) -> usize {
    let old = buf.len();
    buf.extend_from_slice(&[b'0'; WIDTH]);
    old
}

/// Appends the integer `n` scaled by 10^-`decimals` (trailing zeros trimmed): the whole
/// number is formatted on the stack, two digits at a time, and appended in one copy. The
/// usual decimal counts get their own copy with a constant divisor (a multiplication instead
/// of a 64-bit division per number).
#[inline]
pub(super) fn push_scaled(buf: &mut Vec<u8>, n: i64, decimals: u32) {
    match decimals {
        0 => push_scaled_const::<0>(buf, n),
        1 => push_scaled_const::<1>(buf, n),
        2 => push_scaled_const::<2>(buf, n),
        3 => push_milli(buf, n),
        4 => push_scaled_const::<4>(buf, n),
        5 => push_scaled_const::<5>(buf, n),
        _ => push_scaled_with(buf, n, decimals.min(18), 10u64.pow(decimals.min(18))),
    }
}

/// `.xyz` of every thousandth 0..1000 with trailing zeros (and, for 0, the point) trimmed:
/// (length, bytes).
const MILLI: [(u8, [u8; 4]); 1000] = {
    let mut t = [(0u8, [0u8; 4]); 1000];
    let mut k = 1;
    while k < 1000 {
        let d = [(k / 100) as u8, (k / 10 % 10) as u8, (k % 10) as u8];
        let len = if d[2] != 0 {
            4
        } else if d[1] != 0 {
            3
        } else {
            2
        };
        t[k] = (len, [b'.', b'0' + d[0], b'0' + d[1], b'0' + d[2]]);
        k += 1;
    }
    t
};

/// `push_scaled(buf, n, 3)`, the writer's usual case (millimetres to the micrometre): the
/// integer part two digits at a time, the fraction from a table, written in place.
#[inline]
fn push_milli(buf: &mut Vec<u8>, n: i64) {
    let a = n.unsigned_abs();
    let int = a / 1000;
    if int >= 10_000 {
        return push_scaled_const::<3>(buf, n);
    }
    let old = open_slot::<16>(buf);
    let dst = &mut buf[old..];
    let mut i = 0;
    if n < 0 {
        dst[0] = b'-';
        i = 1;
    }
    let int = int as usize;
    if int >= 100 {
        let hi = if int >= 1000 {
            dst[i] = b'0' + (int / 1000) as u8;
            i += 1;
            int / 100 % 10
        } else {
            int / 100
        };
        dst[i] = b'0' + hi as u8;
        let lo = int % 100 * 2;
        dst[i + 1] = DIGITS2[lo];
        dst[i + 2] = DIGITS2[lo + 1];
        i += 3;
    } else if int >= 10 {
        dst[i] = DIGITS2[int * 2];
        dst[i + 1] = DIGITS2[int * 2 + 1];
        i += 2;
    } else {
        dst[i] = b'0' + int as u8;
        i += 1;
    }
    let (len, frac) = MILLI[(a % 1000) as usize];
    dst[i..i + 4].copy_from_slice(&frac);
    i += len as usize;
    buf.truncate(old + i);
}

#[inline]
fn push_scaled_const<const D: u32>(buf: &mut Vec<u8>, n: i64) {
    push_scaled_with(buf, n, D, const { 10u64.pow(D) })
}

/// `push_scaled` for `scale` = 10^`decimals` (`decimals` ≤ 18), written in place.
#[inline(always)]
fn push_scaled_with(buf: &mut Vec<u8>, n: i64, decimals: u32, scale: u64) {
    let a = n.unsigned_abs();
    let (int, mut frac) = (a / scale, a % scale);
    let mut d = decimals as usize;
    if frac == 0 {
        d = 0;
    } else {
        while frac % 10 == 0 {
            frac /= 10;
            d -= 1;
        }
    }
    let len = usize::from(n < 0) + digit_count(int) + if d > 0 { d + 1 } else { 0 };
    // Sign + 20 integer digits + point + 18 decimals fit in 48.
    let old = open_slot::<48>(buf);
    let dst = &mut buf[old..];
    let mut end = len;
    if d > 0 {
        // The fraction's leading zeros are the slot's '0's.
        digits_into(dst, end, frac);
        end -= d + 1;
        dst[end] = b'.';
    }
    digits_into(dst, end, int);
    if n < 0 {
        dst[0] = b'-';
    }
    buf.truncate(old + len);
}

pub(super) fn push_u64(buf: &mut Vec<u8>, v: u64) {
    let len = digit_count(v);
    let old = open_slot::<24>(buf);
    digits_into(&mut buf[old..], len, v);
    buf.truncate(old + len);
}
