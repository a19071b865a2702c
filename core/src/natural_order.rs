//! Names in the order their numbers count: `img2.png` before `img10.png`. Cameras and loggers
//! often number their files without padding, and in plain alphabetical order `img10` comes
//! between `img1` and `img2`, which scrambles a recording's time order without a sign.

use std::cmp::Ordering;
use std::path::{Path, PathBuf};

/// Compares `a` and `b` with every run of ASCII digits taken as one number (of any length),
/// the rest character by character. Numbers equal in value but padded differently (`07`, `7`)
/// and names equal in every other way fall back to plain order, so the order is total and
/// agrees with plain order on names whose numbers all have the same digit count.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut x, mut y) = (a.as_bytes(), b.as_bytes());
    // Whether the names so far end in a number and a decimal point: the digits after it are
    // a fraction (frames named by their timestamps, `1700000000.1` after
    // `1700000000.033333`), compared digit by digit, not as a count.
    let (mut after_number, mut fraction) = (false, false);
    loop {
        match (x.first(), y.first()) {
            (None, None) => return a.cmp(b),
            (None, Some(_)) => return Ordering::Less,
            (Some(_), None) => return Ordering::Greater,
            (Some(p), Some(q)) if p.is_ascii_digit() && q.is_ascii_digit() => {
                let (m, rest_x) = split_digits(x);
                let (n, rest_y) = split_digits(y);
                let by_value = if fraction {
                    // Trailing zeros say nothing of a fraction's value.
                    strip_trailing_zeros(m).cmp(strip_trailing_zeros(n))
                } else {
                    // Leading zeros say nothing of the value: compare the significant
                    // digits, the longer being the larger.
                    let (m, n) = (strip_zeros(m), strip_zeros(n));
                    m.len().cmp(&n.len()).then_with(|| m.cmp(n))
                };
                if by_value != Ordering::Equal {
                    return by_value;
                }
                (x, y) = (rest_x, rest_y);
                (after_number, fraction) = (true, false);
            }
            (Some(p), Some(q)) => {
                if p != q {
                    return p.cmp(q);
                }
                fraction = after_number && *p == b'.';
                after_number = false;
                (x, y) = (&x[1..], &y[1..]);
            }
        }
    }
}

fn strip_trailing_zeros(s: &[u8]) -> &[u8] {
    let end = s.iter().rposition(|c| *c != b'0').map_or(0, |i| i + 1);
    &s[..end]
}

fn split_digits(s: &[u8]) -> (&[u8], &[u8]) {
    let end = s
        .iter()
        .position(|c| !c.is_ascii_digit())
        .unwrap_or(s.len());
    s.split_at(end)
}

fn strip_zeros(s: &[u8]) -> &[u8] {
    let start = s.iter().position(|c| *c != b'0').unwrap_or(s.len());
    &s[start..]
}

/// [`natural_cmp`] of two paths as written (`run2/s10` before `run10/s1`).
pub fn natural_path_cmp(a: &Path, b: &Path) -> Ordering {
    natural_cmp(&a.to_string_lossy(), &b.to_string_lossy())
}

/// Sorts `paths` in natural order ([`natural_cmp`]): the order of a recording's numbered files.
pub fn sort_naturally(paths: &mut [PathBuf]) {
    paths.sort_by(|a, b| natural_path_cmp(a, b));
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sorted(names: &[&str]) -> Vec<String> {
        let mut v: Vec<PathBuf> = names.iter().map(PathBuf::from).collect();
        sort_naturally(&mut v);
        v.iter().map(|p| p.display().to_string()).collect()
    }

    #[test]
    fn digits_after_a_decimal_point_are_a_fraction() {
        // Frames named by their timestamps, printed with as many decimals as they need.
        assert_eq!(
            sorted(&[
                "1700000000.1.png",
                "1700000000.033333.png",
                "1700000000.066667.png",
                "1700000000.2.png",
                "1700000000.133333.png",
                "1700000001.png",
            ]),
            [
                "1700000000.033333.png",
                "1700000000.066667.png",
                "1700000000.1.png",
                "1700000000.133333.png",
                "1700000000.2.png",
                "1700000001.png",
            ]
        );
        // A dot after letters is no decimal point: `img.10` still counts past `img.9`.
        assert_eq!(
            sorted(&["img.10.png", "img.9.png"]),
            ["img.9.png", "img.10.png"]
        );
    }

    #[test]
    fn numbers_count_instead_of_spelling() {
        assert_eq!(
            sorted(&["img10.png", "img2.png", "img0.png", "img1.png", "img11.png"]),
            ["img0.png", "img1.png", "img2.png", "img10.png", "img11.png"]
        );
        // Zero-padded names keep their plain order.
        assert_eq!(
            sorted(&["frame_000010.png", "frame_000009.png", "frame_000100.png"]),
            ["frame_000009.png", "frame_000010.png", "frame_000100.png"]
        );
        // Several numbers, folders, and numbers longer than any integer type.
        assert_eq!(
            sorted(&["run2/s10.csv", "run10/s1.csv", "run2/s9.csv"]),
            ["run2/s9.csv", "run2/s10.csv", "run10/s1.csv"]
        );
        assert_eq!(
            natural_cmp("t100000000000000000000000", "t99999999999999999999999"),
            Ordering::Greater
        );
    }

    #[test]
    fn the_order_is_total() {
        assert_eq!(natural_cmp("a07", "a7"), "a07".cmp("a7"));
        assert_eq!(natural_cmp("a7", "a7"), Ordering::Equal);
        assert_eq!(natural_cmp("a", "a1"), Ordering::Less);
        assert_eq!(natural_cmp("b", "a10"), Ordering::Greater);
        assert_eq!(natural_cmp("x1y", "x1z"), Ordering::Less);
    }
}
