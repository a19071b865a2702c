//! Encoder counters that wrap. A robot's wheel counts are usually a 16- or 32-bit register
//! (8-bit on small motor boards), signed or not, that the firmware logs as it is: after 65 536 ticks a 16-bit counter goes
//! from 65 535 to 0 (or from 32 767 to −32 768), and read as a count that is a step of one
//! wheel's worth of hundreds of metres in 0.2 s. Such a step is unwrapped where the rest of
//! the step is what the wheel does between the other rows; any other jump is left for the
//! dataset's checks to refuse.

/// Widths of the counters unwrapped, bits, widest first (8-bit counters are unwrapped on
/// their own, see [`unwrap_8_bit`]): a 32-bit step is also a whole
/// number of 16-bit turns, and is named by its own width.
const COUNTER_BITS: [u32; 2] = [32, 16];

/// Slack on what a wheel does between two rows at a wrap, ticks: the step left after
/// taking out the counter's turns may be this much beyond twice the log's largest ordinary
/// step (a robot speeding up as its counter wraps).
const STEP_SLACK_TICKS: f64 = 100.0;

/// [`STEP_SLACK_TICKS`] for an 8-bit counter, whose wheel moves a few ticks a row.
const EIGHT_BIT_SLACK_TICKS: f64 = 8.0;

/// The range of counts a 16- or 32-bit counter gives, signed or not.
const COUNTER_RANGE: std::ops::RangeInclusive<f64> = -2_147_483_648.0..=4_294_967_295.0;

/// Whether a step from or to `count` is no 16- or 32-bit counter's wrap: a count beyond
/// their range is a 64-bit counter's, which does not wrap in a robot's life, or a glitch (a
/// `1e30`). Read as a number, a huge count is a whole number of 2³² turns from its neighbours,
/// and was "unwrapped" to a count that is nowhere in the file.
pub fn beyond_32_bit(count: f64) -> bool {
    !COUNTER_RANGE.contains(&count)
}

/// A count in a tick column that no wheel's counter reaches from the column's other counts:
/// more than 2⁵³ ticks (thousands of light years of wheel) from their median, which no step of
/// a 64-bit count read as a number keeps exact either. A glitch (a `1e30`, a garbled
/// `18446744073709551615` among counts of a few thousand).
#[derive(Debug, Clone, PartialEq)]
pub struct CountBeyondCounters {
    /// The wheel's column, `left_ticks` or `right_ticks`.
    pub column: &'static str,
    /// The file's line.
    pub line: u64,
    /// The count as written in the file.
    pub written: String,
    /// The column's median count, as an integer.
    pub median: i128,
}

impl std::fmt::Display for CountBeyondCounters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "line {}: {} is {}, more than 2^53 ticks from the column's other counts (around {}), farther than any wheel turns: a glitch in the log?",
            self.line, self.column, self.written, self.median
        )
    }
}

/// One wrap of a wheel's counter that was unwrapped.
#[derive(Debug, Clone, PartialEq)]
pub struct CounterWrap {
    /// The wheel's column, `left_ticks` or `right_ticks`.
    pub column: &'static str,
    /// The file's line of the row after the wrap.
    pub line: u64,
    /// The counter's width, bits.
    pub bits: u32,
    /// The counts on the rows before and after the wrap, as logged.
    pub from: f64,
    /// See `from`.
    pub to: f64,
}

impl std::fmt::Display for CounterWrap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} wraps as {} {}-bit counter at line {} ({} → {})",
            self.column,
            if self.bits == 8 { "an" } else { "a" },
            self.bits,
            self.line,
            self.from,
            self.to
        )
    }
}

/// Unwraps the counts `v` of the wheel `column` in place (`lines[i]` is row i's line in the
/// file) and returns the wraps taken out.
pub fn unwrap_counts(v: &mut [f64], column: &'static str, lines: &[u64]) -> Vec<CounterWrap> {
    if let Some(wraps) = unwrap_8_bit(v, column, lines) {
        return wraps;
    }
    let logged = v.to_vec();
    let steps: Vec<f64> = logged.windows(2).map(|w| w[1] - w[0]).collect();
    let half_turn_16 = 2f64.powi(15);
    // What the wheel does between rows: the largest step that is no counter turn.
    let ordinary = steps
        .iter()
        .map(|s| s.abs())
        .filter(|s| *s < half_turn_16)
        .fold(0.0, f64::max);
    let mut wraps = Vec::new();
    let mut offset = 0.0;
    for (i, step) in steps.iter().enumerate() {
        let glitch = logged[i..i + 2].iter().any(|&c| beyond_32_bit(c));
        let widths: &[u32] = if glitch { &[] } else { &COUNTER_BITS };
        for &bits in widths {
            let turn = 2f64.powi(bits as i32);
            if step.abs() < turn / 2.0 {
                continue;
            }
            let turns = (step / turn).round();
            if (step - turns * turn).abs() <= 2.0 * ordinary + STEP_SLACK_TICKS {
                offset -= turns * turn;
                wraps.push(CounterWrap {
                    column,
                    line: lines.get(i + 1).copied().unwrap_or(0),
                    bits,
                    from: logged[i],
                    to: logged[i + 1],
                });
                break;
            }
        }
        if offset != 0.0 {
            v[i + 1] += offset;
        }
    }
    wraps
}

/// An 8-bit counter (a small motor board's register): every count lies in 0 to 255 (or −128
/// to 127) and some step spans half the counter or more. It turns every 256 ticks, so it is
/// unwrapped only when every step, taken as the nearest to zero of its whole turns, is within
/// a quarter turn: a wheel that moves more between rows could have turned any number of
/// times, and is left for the dataset's checks. None when the column is not such a counter.
fn unwrap_8_bit(v: &mut [f64], column: &'static str, lines: &[u64]) -> Option<Vec<CounterWrap>> {
    const TURN: f64 = 256.0;
    let unsigned = v.iter().all(|c| (0.0..TURN).contains(c));
    let signed = v.iter().all(|c| (-TURN / 2.0..TURN / 2.0).contains(c));
    let steps: Vec<f64> = v.windows(2).map(|w| w[1] - w[0]).collect();
    if !(unsigned || signed) || !steps.iter().any(|s| s.abs() >= TURN / 2.0) {
        return None;
    }
    let moved: Vec<f64> = steps
        .iter()
        .map(|s| s - (s / TURN).round() * TURN)
        .collect();
    // As for the wider counters, a wrap's step must be what the wheel does between the other
    // rows: 210 → 0 among steps of 10 is a reset, not a wrap of +46.
    let ordinary = steps
        .iter()
        .filter(|s| s.abs() < TURN / 2.0)
        .fold(0.0, |a: f64, s| a.max(s.abs()));
    let at_wraps = steps.iter().zip(&moved).filter(|(s, m)| s != m);
    if moved.iter().any(|m| m.abs() > TURN / 4.0)
        || at_wraps
            .into_iter()
            .any(|(_, m)| m.abs() > 2.0 * ordinary + EIGHT_BIT_SLACK_TICKS)
    {
        return None;
    }
    let logged = v.to_vec();
    let mut wraps = Vec::new();
    for (i, (step, m)) in steps.iter().zip(&moved).enumerate() {
        if step != m {
            wraps.push(CounterWrap {
                column,
                line: lines.get(i + 1).copied().unwrap_or(0),
                bits: 8,
                from: logged[i],
                to: logged[i + 1],
            });
        }
        v[i + 1] = v[i] + m;
    }
    Some(wraps)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unwrap(v: &[f64]) -> (Vec<f64>, Vec<CounterWrap>) {
        let mut v = v.to_vec();
        let lines: Vec<u64> = (2..2 + v.len() as u64).collect();
        let w = unwrap_counts(&mut v, "left_ticks", &lines);
        (v, w)
    }

    #[test]
    fn sixteen_and_thirty_two_bit_wraps_are_taken_out() {
        // Unsigned 16-bit, forwards.
        let (v, w) = unwrap(&[65500.0, 65520.0, 4.0, 25.0]);
        assert_eq!(v, vec![65500.0, 65520.0, 65540.0, 65561.0]);
        assert_eq!(w.len(), 1);
        assert_eq!(
            w[0].to_string(),
            "left_ticks wraps as a 16-bit counter at line 4 (65520 → 4)"
        );
        // Signed 16-bit, backwards (the wheel turning back through −32768).
        let (v, w) = unwrap(&[-32750.0, -32765.0, 32757.0, 32740.0]);
        assert_eq!(v, vec![-32750.0, -32765.0, -32779.0, -32796.0]);
        assert_eq!((w.len(), w[0].bits), (1, 16));
        // Signed 32-bit.
        let max = 2f64.powi(31) - 1.0;
        let (v, w) = unwrap(&[max - 10.0, max, -max - 1.0 + 9.0]);
        assert_eq!(v[2], max + 10.0);
        assert_eq!((w.len(), w[0].bits), (1, 32));
        // Twice in one log: both taken out, the counts keep climbing.
        let mut up: Vec<f64> = (0..20).map(|k| ((k * 9000) % 65536) as f64).collect();
        let lines: Vec<u64> = (0..20).collect();
        let w = unwrap_counts(&mut up, "right_ticks", &lines);
        assert_eq!(w.len(), 2);
        assert!(up.windows(2).all(|s| s[1] - s[0] == 9000.0), "{up:?}");
    }

    #[test]
    fn eight_bit_wraps_are_taken_out_and_resets_left() {
        // A small motor board's counter: 253 + 9 − 256 = 6 was called a counter reset.
        let (v, w) = unwrap(&[235.0, 244.0, 253.0, 6.0, 15.0, 24.0]);
        assert_eq!(v, vec![235.0, 244.0, 253.0, 262.0, 271.0, 280.0]);
        assert_eq!(
            w.iter().map(ToString::to_string).collect::<Vec<_>>(),
            vec!["left_ticks wraps as an 8-bit counter at line 5 (253 → 6)"]
        );
        // Signed, backwards through −128.
        let (v, w) = unwrap(&[-120.0, -126.0, 124.0, 118.0]);
        assert_eq!(v, vec![-120.0, -126.0, -132.0, -138.0]);
        assert_eq!((w.len(), w[0].bits), (1, 8));
        // A reset to zero among steps of 10, and a wheel too fast for 8 bits: left.
        for v in [[200.0, 210.0, 0.0, 10.0], [0.0, 100.0, 200.0, 44.0]] {
            let (u, w) = unwrap(&v);
            assert!(w.is_empty(), "{w:?}");
            assert_eq!(u, v.to_vec());
        }
    }

    #[test]
    fn counts_no_32_bit_counter_gives_are_no_wrap() {
        // 2^64 and 1e30 are whole numbers of 2^32 turns from 0: they were "unwrapped" to 0.
        for glitch in [18446744073709551615.0, 1e30, -1e300] {
            let v = [95.0, 99.0, glitch, 104.0];
            let (u, w) = unwrap(&v);
            assert!(w.is_empty(), "{w:?}");
            assert_eq!(u, v.to_vec());
        }
    }

    #[test]
    fn jumps_that_are_no_wrap_are_left() {
        // A counter reset to zero, and a jump half a turn off: not a wrap.
        for v in [[40000.0, 40010.0, 0.0, 10.0], [0.0, 10.0, 32768.0, 32778.0]] {
            let (u, w) = unwrap(&v);
            assert!(w.is_empty(), "{w:?}");
            assert_eq!(u, v.to_vec());
        }
        // Ordinary logs are untouched.
        let (u, w) = unwrap(&[0.0, 3.0, 7.0, 7.0]);
        assert!(w.is_empty());
        assert_eq!(u, vec![0.0, 3.0, 7.0, 7.0]);
    }
}
