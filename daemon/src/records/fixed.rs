//! Numbers at a fixed precision, written straight into a byte buffer: the flight-data CSV's
//! cells, a few hundred thousand a second. The standard library's `{:.4}` writes the exact
//! decimal value of the double rounded half to even, and falls back to big-number arithmetic
//! for it; here the value is scaled to an integer, `p = x × 10^d` rounded half to even, and
//! its digits written: the same text. The product rounds once, but a rounding of `p` can only
//! go the other way from the exact value's when `p` sits on a half, and there the product's
//! exact error (a fused multiply-add) settles it. Values too large for that (|x| × 10^d ≥
//! 2^51), NaN and infinities go through the standard library.

use std::io::Write;

const POW10: [f64; 10] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9];
const POW10_U64: [u64; 10] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
    1_000_000_000,
];
const TWO_52: f64 = 4_503_599_627_370_496.0;
const TWO_51: f64 = 2_251_799_813_685_248.0;
/// A double's 52 mantissa bits.
const MANTISSA: u64 = (1 << 52) - 1;
/// "00" to "99": two digits per lookup.
const PAIRS: &[u8; 200] = b"0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Appends `x` with `decimals` (at most 9) digits after the point, as `{:.decimals$}` does.
pub fn push_fixed(out: &mut Vec<u8>, x: f64, decimals: usize) {
    let d = decimals.min(POW10.len() - 1);
    let p = x.abs() * POW10[d];
    if !p.is_finite() || p >= TWO_51 {
        // From 2^51, or not finite: the standard library (writing to a Vec cannot fail).
        let _ = write!(out, "{x:.d$}");
        return;
    }
    // Rounded half to even by the hardware's own rounding: below 2^52, adding 2^52 leaves no
    // fraction bits (as `round_ties_even`, without a call to libm's `rint`); the sum's
    // mantissa is then the rounded integer itself (below 2^51, the sum stays under 2^53).
    let biased = p + TWO_52;
    let scaled = biased - TWO_52;
    let mut n = biased.to_bits() & MANTISSA;
    // Below 2^52, p - scaled is exact; off a half, the product's error (under half an ulp of
    // p) cannot carry the exact value past one.
    if (p - scaled).abs() == 0.5 {
        let error = x.abs().mul_add(POW10[d], -p);
        if p > scaled && error > 0.0 {
            n += 1;
        } else if p < scaled && error < 0.0 {
            n -= 1;
        }
    }
    // The digits from the last, two at a time: d of the fraction, the point, the integer part.
    let unit = POW10_U64[d];
    let (mut int, mut frac) = (n / unit, n % unit);
    let mut text = [0u8; 32];
    let mut at = text.len();
    let mut left = d;
    while left >= 2 {
        at -= 2;
        let pair = (frac % 100) as usize * 2;
        text[at..at + 2].copy_from_slice(&PAIRS[pair..pair + 2]);
        frac /= 100;
        left -= 2;
    }
    if left == 1 {
        at -= 1;
        text[at] = b'0' + frac as u8;
    }
    if d > 0 {
        at -= 1;
        text[at] = b'.';
    }
    let units_at = at;
    while int >= 10 {
        at -= 2;
        let pair = (int % 100) as usize * 2;
        text[at..at + 2].copy_from_slice(&PAIRS[pair..pair + 2]);
        int /= 100;
    }
    // The last digit: one left, or the integer part 0 (no digit written for it yet).
    if int > 0 || at == units_at {
        at -= 1;
        text[at] = b'0' + int as u8;
    }
    if x.is_sign_negative() {
        at -= 1;
        text[at] = b'-';
    }
    out.extend_from_slice(&text[at..]);
}

/// Appends an unsigned integer.
pub fn push_int(out: &mut Vec<u8>, n: u64) {
    out.extend_from_slice(itoa::Buffer::new().format(n).as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn fixed(x: f64, d: usize) -> String {
        let mut out = Vec::new();
        push_fixed(&mut out, x, d);
        String::from_utf8(out).unwrap_or_default()
    }

    #[test]
    fn edge_values_read_as_the_standard_library_writes_them() {
        for x in [
            0.0,
            -0.0,
            -0.00001,
            1.0,
            -1.5,
            0.125,
            0.375,
            2.5,
            1e15,
            -1e300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            9_007_199_254_740_993.0,
        ] {
            for d in [0, 1, 3, 4, 6] {
                assert_eq!(fixed(x, d), format!("{x:.d$}"), "{x:e} to {d} places");
            }
        }
    }

    proptest! {
        /// Any double the CSV holds (positions, rates, commands, angles), at every precision it
        /// uses: the standard library's text.
        #[test]
        fn values_read_as_the_standard_library_writes_them(
            x in -1e6f64..1e6, scale in -8i32..4, d in 0usize..=6,
        ) {
            let x = x * 10f64.powi(scale);
            prop_assert_eq!(fixed(x, d), format!("{x:.d$}"));
        }

        /// Decimal halves, which a double holds only approximately (just above or below the
        /// tie) or exactly: the cases a scaled rounding could get wrong.
        #[test]
        fn near_ties_round_as_the_exact_value_does(n in -100_000_000i64..100_000_000, d in 0usize..=6) {
            let x = (n as f64 + 0.5) / 10f64.powi(d as i32);
            prop_assert_eq!(fixed(x, d), format!("{x:.d$}"));
        }
    }
}
