//! Encoder twitches at rest. A wheel standing on the edge of a tick flickers between two
//! counts (vibration, a motor's holding current), so a log at rest shows a count one more or
//! less for a row or a few, and back. That is no motion: read as motion it moves a run's
//! start t_b to the flicker, seconds before the wheel turns, and shifts every input taken
//! from t_b, or makes a log look as if it starts in motion. Such excursions are set back to
//! the count they return to, both wheels together; a wheel that comes back to its count only
//! after moving more than one tick, or while the other wheel moves, is left as it is.

/// Counts at rest flickered by at most this many ticks.
const TWITCH_TICKS: f64 = 1.0;

/// A twitch taken out of a log: its rows read the count of the rows around them.
#[derive(Debug, Clone, PartialEq)]
pub struct Twitch {
    /// The file's lines of the first and last row set back.
    pub lines: (u64, u64),
}

impl std::fmt::Display for Twitch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.lines {
            (a, b) if a == b => write!(f, "line {a}"),
            (a, b) => write!(f, "lines {a}–{b}"),
        }
    }
}

/// Sets the twitches of the counts `left` and `right` back to the count they return to, in
/// place (`lines[i]` is row i's line in the file), and returns them.
pub fn remove_twitches(left: &mut [f64], right: &mut [f64], lines: &[u64]) -> Vec<Twitch> {
    let n = left.len().min(right.len());
    let same = |l: &[f64], r: &[f64], i: usize, j: usize| l[i] == l[j] && r[i] == r[j];
    let mut twitches = Vec::new();
    let mut i = 1;
    while i < n {
        if same(left, right, i, i - 1) {
            i += 1;
            continue;
        }
        let base = i - 1;
        let near = |k: usize| {
            (left[k] - left[base]).abs() <= TWITCH_TICKS
                && (right[k] - right[base]).abs() <= TWITCH_TICKS
        };
        // The excursion's last row: the row before the counts come back to `base`'s. The
        // wheels stand still before it and after it: a wheel rocking back mid-run, or as
        // the robot stops (a tick over and back), is part of the motion.
        let at_rest = |k: usize| k + 1 >= n || same(left, right, k, k + 1);
        let rest_before = base == 0 || same(left, right, base, base - 1);
        let back = (i..n)
            .take_while(|&k| near(k))
            .find(|&k| k + 1 < n && same(left, right, k + 1, base))
            .filter(|&k| rest_before && at_rest(k + 1));
        match back {
            Some(last) => {
                for k in i..=last {
                    left[k] = left[base];
                    right[k] = right[base];
                }
                let line = |k: usize| lines.get(k).copied().unwrap_or(k as u64 + 2);
                twitches.push(Twitch {
                    lines: (line(i), line(last)),
                });
                i = last + 2;
            }
            None => i += 1,
        }
    }
    twitches
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(l: &[f64], r: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<(u64, u64)>) {
        let (mut l, mut r) = (l.to_vec(), r.to_vec());
        let lines: Vec<u64> = (2..2 + l.len() as u64).collect();
        let t = remove_twitches(&mut l, &mut r, &lines);
        (l, r, t.into_iter().map(|t| t.lines).collect())
    }

    #[test]
    fn a_flicker_at_rest_is_taken_out() {
        // One row one tick over and back, then two rows one under and back, then a run.
        let (l, r, t) = run(
            &[5., 6., 5., 5., 4., 4., 5., 5., 6., 8., 10.],
            &[7., 7., 7., 7., 7., 7., 7., 7., 8., 10., 12.],
        );
        assert_eq!(l, [5., 5., 5., 5., 5., 5., 5., 5., 6., 8., 10.]);
        assert_eq!(r[..8], [7.; 8]);
        assert_eq!(t, [(3, 3), (6, 7)]);
    }

    #[test]
    fn motion_is_left_as_it_is() {
        // A slow start (a tick per row or less) never comes back; a wheel back after two
        // ticks moved, as did one rocking a tick between two moves or as the robot stops;
        // a return while the other wheel turns is a turn.
        for (l, r) in [
            (vec![0., 0., 1., 1., 2., 3.], vec![0., 0., 1., 1., 2., 3.]),
            (vec![0., 1., 2., 1., 0., 0.], vec![0., 0., 0., 0., 0., 0.]),
            (vec![0., 1., 2., 1., 2., 3.], vec![0., 1., 2., 1., 2., 3.]),
            (
                vec![0., 2., 4., 5., 4., 4., 4.],
                vec![0., 2., 4., 4., 4., 4., 4.],
            ),
            (vec![0., 1., 0., 0.], vec![0., 1., 2., 2.]),
            (vec![0., 0., 1.], vec![0., 0., 0.]),
        ] {
            let (l2, r2, t) = run(&l, &r);
            assert_eq!((l2, r2), (l, r));
            assert!(t.is_empty());
        }
    }
}
