//! A small JSON writer for the high-rate streams: values are appended to one reused
//! `String`, numbers in fixed point with a per-quantity resolution (no `serde_json::Value`
//! tree, no float-to-shortest conversion). At default rates a run writes about a million
//! messages per 100 drones per 10 simulated seconds, so this is most of the recording's cost.

use std::io::Write as _;

use crate::record::fixed::{POW10, decimal, digits};

/// Decimals of metres and metres per second: 1 mm (well below any sensor's noise; each
/// further digit is noise that zstd cannot compress and costs about 10 % more CPU).
pub const METRES: usize = 3;
/// Decimals of quaternion components (1e-5, about 0.001 degree).
pub const UNIT: usize = 5;
/// Decimals of latitude and longitude, degrees (1e-8 degree is 1.1 mm of latitude).
pub const DEGREES: usize = 8;
/// Decimals of battery and motor values (volts, amperes, mAh, fractions).
pub const COARSE: usize = 4;

/// Appends `v` with at most `decimals` decimals (trailing zeros dropped), `null` when it is
/// not finite (JSON has no NaN). Values too large for fixed point use Rust's shortest form.
pub fn num(out: &mut Vec<u8>, v: f64, decimals: usize) {
    if !v.is_finite() {
        out.extend_from_slice(b"null");
        return;
    }
    let scaled = v.abs() * POW10[decimals] as f64;
    if scaled >= 9.0e15 {
        let _ = write!(out, "{v}");
        return;
    }
    // Round half away from zero (`f64::round` is a libm call on baseline x86-64).
    let mut n = (scaled + 0.5) as u64;
    let mut decimals = decimals;
    while decimals > 0 && n.is_multiple_of(10) {
        n /= 10;
        decimals -= 1;
    }
    let mut buf = [0u8; 32];
    let mut start = decimal(&mut buf, n, decimals);
    // `-0.00001` rounds to 0: written without a sign.
    if v < 0.0 && n != 0 {
        start -= 1;
        buf[start] = b'-';
    }
    out.extend_from_slice(&buf[start..]);
}

/// Appends an unsigned integer.
pub fn uint(out: &mut Vec<u8>, n: u64) {
    let mut buf = [0u8; 20];
    let start = digits(&mut buf, 20, n);
    out.extend_from_slice(&buf[start..]);
}

/// Appends `s` as a JSON string (quotes and escapes included).
pub fn string(out: &mut Vec<u8>, s: &str) {
    out.push(b'"');
    for c in s.chars() {
        match c {
            '"' => out.extend_from_slice(b"\\\""),
            '\\' => out.extend_from_slice(b"\\\\"),
            '\n' => out.extend_from_slice(b"\\n"),
            '\r' => out.extend_from_slice(b"\\r"),
            '\t' => out.extend_from_slice(b"\\t"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.extend_from_slice(c.encode_utf8(&mut [0; 4]).as_bytes()),
        }
    }
    out.push(b'"');
}

/// Appends `true` or `false`.
pub fn boolean(out: &mut Vec<u8>, b: bool) {
    out.extend_from_slice(if b { b"true" } else { b"false" });
}

/// Appends a `foxglove.Time` object for `ns` nanoseconds of simulated time.
pub fn time(out: &mut Vec<u8>, ns: u64) {
    out.extend_from_slice(b"{\"sec\":");
    uint(out, ns / 1_000_000_000);
    out.extend_from_slice(b",\"nsec\":");
    uint(out, ns % 1_000_000_000);
    out.push(b'}');
}

/// Appends `"name":`, the key of an object member; `name` is a plain identifier (nothing
/// to escape).
pub fn key(out: &mut Vec<u8>, name: &str) {
    out.push(b'"');
    out.extend_from_slice(name.as_bytes());
    out.extend_from_slice(b"\":");
}

/// Appends `,"name":value` for each member, `value` written by `write`: members that
/// follow an object's first one.
pub fn members<T: Copy>(out: &mut Vec<u8>, members: &[(&str, T)], write: impl Fn(&mut Vec<u8>, T)) {
    for &(name, value) in members {
        out.push(b',');
        key(out, name);
        write(out, value);
    }
}

/// Appends `,"name":..` for each member: numbers with `decimals` decimals.
pub fn numbers(out: &mut Vec<u8>, members: &[(&str, f64)], decimals: usize) {
    self::members(out, members, |o, v| num(o, v, decimals));
}

/// Appends `items` between `open` and `close`, separated by commas, each written by `write`.
fn list<T>(
    out: &mut Vec<u8>,
    open: u8,
    items: impl IntoIterator<Item = T>,
    close: u8,
    write: impl Fn(&mut Vec<u8>, T),
) {
    out.push(open);
    for (i, item) in items.into_iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        write(out, item);
    }
    out.push(close);
}

/// Appends `{"name":..,..}`: an object of numbers with `decimals` decimals.
fn object(out: &mut Vec<u8>, members: &[(&str, f64)], decimals: usize) {
    list(out, b'{', members, b'}', |o, &(name, v)| {
        key(o, name);
        num(o, v, decimals);
    });
}

/// Appends `[..]`: an array of numbers with `decimals` decimals.
pub fn array(out: &mut Vec<u8>, values: impl IntoIterator<Item = f64>, decimals: usize) {
    list(out, b'[', values, b']', |o, v| num(o, v, decimals));
}

/// Appends `{"x":..,"y":..,"z":..}`.
pub fn vector3(out: &mut Vec<u8>, v: [f64; 3], decimals: usize) {
    object(out, &[("x", v[0]), ("y", v[1]), ("z", v[2])], decimals);
}

/// Appends a `foxglove.Quaternion` from `(w, x, y, z)`.
pub fn quaternion(out: &mut Vec<u8>, wxyz: [f64; 4]) {
    object(out, &[("x", wxyz[1]), ("y", wxyz[2]), ("z", wxyz[3]), ("w", wxyz[0])], UNIT);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn n(v: f64, d: usize) -> String {
        let mut s = Vec::new();
        num(&mut s, v, d);
        String::from_utf8(s).unwrap()
    }

    #[test]
    fn numbers_are_fixed_point_without_trailing_zeros() {
        assert_eq!(n(1.5, 4), "1.5");
        assert_eq!(n(-1.23456, 4), "-1.2346");
        assert_eq!(n(0.00004, 4), "0");
        assert_eq!(n(-0.00004, 4), "0");
        assert_eq!(n(-0.0001, 4), "-0.0001");
        assert_eq!(n(100.0, 4), "100");
        assert_eq!(n(0.000_000_001, 9), "0.000000001");
        assert_eq!(n(41.879_612_345_6, 9), "41.879612346");
        assert_eq!(n(f64::NAN, 4), "null");
        assert_eq!(n(f64::INFINITY, 4), "null");
        assert_eq!(n(1e300, 4), format!("{}", 1e300));
    }

    #[test]
    fn numbers_parse_back_within_half_a_step() {
        for &v in &[0.0, 1.0, -3.75, 123.456_789, -9_876.543_21, 0.000_05, 1e9 + 0.123] {
            let parsed: f64 = serde_json::from_str(&n(v, METRES)).unwrap();
            assert!((parsed - v).abs() <= 0.5e-3 + 1e-12, "{v} -> {parsed}");
        }
    }

    #[test]
    fn numbers_match_rust_formatting_over_many_values() {
        let mut x = 0.123_456_789_f64;
        for i in 0..20_000 {
            x = (x * 7.31 + f64::from(i) * 0.017) % 5_000.0 - 2_500.0;
            for d in [0, 1, 4, 6, 9] {
                let expected: f64 = format!("{x:.d$}").parse().unwrap();
                let got: f64 = n(x, d).parse().unwrap();
                // Ties may round either way: at most one step apart (plus f64 rounding).
                let slack = x.abs() * 1e-15;
                assert!((got - expected).abs() <= 1.0001 / POW10[d] as f64 + slack, "{x} to {d}: {got} vs {expected}");
                assert!((got - x).abs() <= 0.5001 / POW10[d] as f64 + slack, "{x} to {d}: {got}");
            }
        }
        assert_eq!(n(0.05, 2), "0.05");
        assert_eq!(n(-0.05, 2), "-0.05");
        assert_eq!(n(10.0001, 4), "10.0001");
        assert_eq!(n(123_456_789.0, 0), "123456789");
    }

    #[test]
    fn strings_are_escaped() {
        let mut s = Vec::new();
        string(&mut s, "a\"b\\c\nd\u{1}é");
        let s = String::from_utf8(s).unwrap();
        assert_eq!(s, r#""a\"b\\c\nd\u0001é""#);
        let back: String = serde_json::from_str(&s).unwrap();
        assert_eq!(back, "a\"b\\c\nd\u{1}é");
    }

    #[test]
    fn time_splits_seconds_and_nanoseconds() {
        let mut s = Vec::new();
        time(&mut s, 12_340_000_001);
        assert_eq!(s, br#"{"sec":12,"nsec":340000001}"#);
    }
}
