//! Fixed-point decimals for the text written every window: the digit writer shared with
//! `recording.mcap`'s JSON messages ([`digits`], [`decimal`]), and [`push`] for
//! `trajectory.csv`, exactly what `format!("{v:.N}")` writes without going through
//! `core::fmt`'s exact float formatting (Grisu with a Dragon fallback, about 1 500
//! instructions a number), which was most of the coordinator thread's work at 1 000 drones.
//!
//! [`push`]'s fast path scales `|v|` by `10^N` (one rounding, relative error ≤ 2⁻⁵³) and
//! rounds to the nearest integer. That integer is the correctly rounded one whenever the
//! scaled value is farther from a half than the scaling's error can reach; values close to a
//! half (one in about a thousand), too large, or not finite go through `format!` itself, so
//! the text is the same in every case (tested against `format!` on millions of values).

use std::io::Write as _;

/// Powers of ten for the supported precisions (0..=10 decimals).
pub(crate) const POW10: [u64; 11] =
    [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000, 100_000_000, 1_000_000_000, 10_000_000_000];

/// "00" to "99": two digits per division.
const PAIRS: &[u8; 200] = b"0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Writes the decimal digits of `n` so that they end at `buf[end]` (exclusive); returns
/// where they start. `buf` must have room for 20 digits before `end`.
///
/// Inlined: it runs for every number of every window on the coordinator's and the
/// recorder's threads, and as a call it cost `trajectory.csv` about 55 instructions per
/// drone-step on the coordinator's critical path (callgrind).
#[inline(always)]
pub(crate) fn digits(buf: &mut [u8], mut end: usize, mut n: u64) -> usize {
    while n >= 100 {
        let pair = (n % 100) as usize * 2;
        n /= 100;
        end -= 2;
        buf[end..end + 2].copy_from_slice(&PAIRS[pair..pair + 2]);
    }
    if n >= 10 {
        let pair = n as usize * 2;
        end -= 2;
        buf[end..end + 2].copy_from_slice(&PAIRS[pair..pair + 2]);
    } else {
        end -= 1;
        buf[end] = b'0' + n as u8;
    }
    end
}

/// Writes `n / 10^decimals` with exactly `decimals` decimals (`1234, 3` -> `1.234`,
/// `5, 2` -> `0.05`, no point for 0 decimals) at the end of `buf`; returns where it starts.
/// `buf` must hold 32 bytes; `decimals` is at most 10. Inlined, as [`digits`].
#[inline(always)]
pub(crate) fn decimal(buf: &mut [u8; 32], n: u64, decimals: usize) -> usize {
    let end = buf.len();
    if decimals == 0 {
        return digits(buf, end, n);
    }
    let scale = POW10[decimals];
    let mut start = digits(buf, end, n % scale);
    // Leading zeros of the fraction (0.05 -> "05").
    while end - start < decimals {
        start -= 1;
        buf[start] = b'0';
    }
    start -= 1;
    buf[start] = b'.';
    digits(buf, start, n / scale)
}

/// Scaled values below this take the fast path: their scaling error is at most
/// 2⁴⁰ × 2⁻⁵³ = 2⁻¹³, far inside [`TIE_MARGIN`].
const FAST_LIMIT: f64 = (1u64 << 40) as f64;

/// How far from a half (in units of the last decimal) the fast path's rounding must be.
const TIE_MARGIN: f64 = 1.0 / 1024.0;

/// Appends `v` with exactly `decimals` decimals (at most 10), as `write!(out, "{v:.decimals$}")`
/// does.
pub fn push(out: &mut Vec<u8>, v: f64, decimals: usize) {
    let scale = POW10[decimals];
    let scaled = v.abs() * scale as f64;
    // NaN and infinities go there too.
    if scaled.is_nan() || scaled >= FAST_LIMIT {
        let _ = write!(out, "{v:.decimals$}");
        return;
    }
    let whole = scaled as u64; // truncation: scaled is finite, non-negative, below 2^40
    let fraction = scaled - whole as f64; // exact (Sterbenz)
    if (fraction - 0.5).abs() < TIE_MARGIN {
        let _ = write!(out, "{v:.decimals$}");
        return;
    }
    let n = if fraction > 0.5 { whole + 1 } else { whole };
    // `format!` keeps the sign of negative values that round to zero ("-0.000").
    if v.is_sign_negative() {
        out.push(b'-');
    }
    let mut buf = [0u8; 32];
    let start = decimal(&mut buf, n, decimals);
    out.extend_from_slice(&buf[start..]);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fast(v: f64, decimals: usize) -> String {
        let mut out = Vec::new();
        push(&mut out, v, decimals);
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn the_text_is_what_format_writes_on_edge_cases() {
        let edges = [
            0.0,
            -0.0,
            -0.0001,
            0.0005,
            0.0015,
            0.0025,
            2.5,
            -2.5,
            0.125,
            1.0e-300,
            123_456.789_5,
            41.879_6,
            -87.623_7,
            1.0e9,
            1.0e12,
            -1.0e15,
            1.0e300,
            f64::MAX,
            f64::MIN_POSITIVE,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for v in edges {
            for d in 0..=9 {
                assert_eq!(fast(v, d), format!("{v:.d$}"), "{v:e} with {d} decimals");
            }
        }
    }

    #[test]
    fn the_text_is_what_format_writes_on_millions_of_values() {
        let mut rng = sadesim_crds::random::Rng::stream(7, 0, sadesim_crds::random::Purpose::Turbulence);
        let mut near_half = 0;
        for i in 0..2_000_000u32 {
            // Magnitudes from 1e-6 to 1e9, both signs, and values on a decimal grid (ties).
            let magnitude = 10f64.powf(rng.next_f64() * 15.0 - 6.0);
            let v = if i % 4 == 0 {
                (rng.next_f64() * 1e6).round() / 2e3 - 250.0
            } else {
                (rng.next_f64() - 0.5) * magnitude
            };
            let d = (i % 10) as usize;
            let scaled = v.abs() * POW10[d] as f64;
            if (scaled.fract() - 0.5).abs() < TIE_MARGIN {
                near_half += 1;
            }
            assert_eq!(fast(v, d), format!("{v:.d$}"), "{v:e} with {d} decimals");
        }
        // The grid quarter makes many exact halves: the fallback was exercised.
        assert!(near_half > 10_000, "{near_half}");
    }
}
