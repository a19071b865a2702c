//! A scan's beams in the order they are read. A scan of less than a full turn is read from
//! its first beam, and its ends are the edges of the field of view. A full turn (a 360°
//! scanner) has no edges, so it is not read from wherever its driver starts the array: a
//! reflector across that beam would be cut in two, and the beams either side of it taken for
//! the view's edges. The same returns written from 0 to 2π instead of from −π to π gave other
//! poses (3.6 mm RMS against 3.0, one pose 9σ off). A full turn is read from the first
//! return after its widest sector without a return (the rear the robot's body masks, whose
//! ends are then the view's edges, as a partial scan's are); with a return in every
//! direction it is read from a beam that is no reflector's and its ends are neighbours.

use std::f64::consts::TAU;

use odocal_core::wrap_angle;

use crate::{Scan, SensorConfig};

/// A scan's beams from its seam; `k` below is a beam's place in the sweep, not in the array.
pub(crate) struct Sweep<'a> {
    scan: &'a Scan,
    /// Array index of the sweep's first beam.
    start: usize,
    /// Beams in the sweep: a full turn's last beam that repeats its first's direction (a scan
    /// written from −π to π with both ends) is left out.
    n: usize,
    step_rad: f64,
    /// A full turn.
    turn: bool,
    /// A full turn with a return in every direction: its last beam neighbours its first.
    closed: bool,
    min_range_m: f64,
}

/// The beams of a full turn (without a last beam repeating the first's direction), or None
/// for a scan of less than a turn.
fn turn_beams(scan: &Scan) -> Option<usize> {
    let step = scan.step_rad();
    let n = scan.angles_rad.len();
    if n < 2 || step <= 0.0 {
        return None;
    }
    let per_turn = (TAU / step).round() as usize;
    let span_rad = (n - 1) as f64 * step;
    if n == per_turn {
        Some(n)
    } else if n == per_turn + 1 && (span_rad - TAU).abs() < 0.1 * step {
        Some(per_turn)
    } else {
        None
    }
}

impl<'a> Sweep<'a> {
    /// The sweep of `scan` for a sensor with `sens`'s range limits and reflector intensity.
    pub(crate) fn new(scan: &'a Scan, sens: &SensorConfig) -> Sweep<'a> {
        let mut sweep = Sweep {
            scan,
            start: 0,
            n: scan.ranges_m.len(),
            step_rad: scan.step_rad(),
            turn: false,
            closed: false,
            min_range_m: sens.min_range_m,
        };
        let Some(n) = turn_beams(scan) else {
            return sweep;
        };
        sweep.n = n;
        sweep.turn = true;
        let returns = |i: usize| scan.ranges_m[i] >= sens.min_range_m;
        // Where a beam points, the same whichever beam the array starts at: it decides
        // between equally good seams.
        let bearing = |i: usize| wrap_angle(scan.angles_rad[i]);
        let Some(r0) = (0..n).find(|&i| returns(i)) else {
            return sweep;
        };
        // The widest run of beams without a return (length, and the return after it).
        let mut widest: Option<(usize, usize)> = None;
        let mut run = 0;
        for k in 1..=n {
            let i = (r0 + k) % n;
            if !returns(i) {
                run += 1;
                continue;
            }
            let wider = widest.is_none_or(|(len, after)| {
                run > len || (run == len && bearing(i) < bearing(after))
            });
            if run > 0 && wider {
                widest = Some((run, i));
            }
            run = 0;
        }
        match widest {
            Some((_, after)) => sweep.start = after,
            None => {
                let reflective = |i: usize| {
                    scan.ranges_m[i] <= sens.max_range_m
                        && scan.intensities[i] >= sens.intensity_min
                };
                sweep.start = (0..n)
                    .filter(|&i| !reflective(i))
                    .min_by(|&a, &b| bearing(a).total_cmp(&bearing(b)))
                    .unwrap_or(0);
                sweep.closed = true;
            }
        }
        sweep
    }

    /// Number of beams.
    pub(crate) fn len(&self) -> usize {
        self.n
    }

    /// Whether the sweep goes round with a return in every direction (no edge to its view).
    pub(crate) fn is_closed(&self) -> bool {
        self.closed
    }

    pub(crate) fn index(&self, k: usize) -> usize {
        (self.start + k) % self.n
    }

    /// Range of beam `k`, metres.
    pub(crate) fn range_m(&self, k: usize) -> f64 {
        self.scan.ranges_m[self.index(k)]
    }

    /// Intensity of beam `k`.
    pub(crate) fn intensity(&self, k: usize) -> f64 {
        self.scan.intensities[self.index(k)]
    }

    /// Angle of beam `k`, radians, increasing through the sweep (past the array's end a turn
    /// is added).
    pub(crate) fn angle_rad(&self, k: usize) -> f64 {
        let turns = ((self.start + k) / self.n) as f64;
        self.scan.angles_rad[self.index(k)] + turns * TAU
    }

    /// Beam `k` of the sweep counted on either side of it: None beyond its ends, except round
    /// a closed sweep.
    pub(crate) fn neighbour(&self, k: isize) -> Option<usize> {
        let n = self.n as isize;
        if (0..n).contains(&k) {
            Some(k as usize)
        } else if self.closed {
            Some(k.rem_euclid(n) as usize)
        } else {
            None
        }
    }

    /// The first and last beams with a return: the scanner sees between them. Beyond them is
    /// a sector without a single return, which is no view of empty space but one the scanner
    /// does not have (the rear of a 360° scanner masked by the robot's body, say). None when
    /// no beam returned.
    pub(crate) fn returning_span(&self) -> Option<(usize, usize)> {
        let returns = |k: &usize| self.range_m(*k) >= self.min_range_m;
        Some(((0..self.n).find(returns)?, (0..self.n).rfind(returns)?))
    }

    /// `angle_rad` moved by whole turns to within half a turn of the sweep's middle, the
    /// branch its beams' angles are on.
    pub(crate) fn unwrap(&self, angle_rad: f64) -> f64 {
        let mid = 0.5 * (self.angle_rad(0) + self.angle_rad(self.n.saturating_sub(1)));
        angle_rad + TAU * ((mid - angle_rad) / TAU).round()
    }

    /// The beam nearest to `angle_rad` (any turn), if inside the scan.
    pub(crate) fn beam_at(&self, angle_rad: f64) -> Option<usize> {
        if self.n < 2 || self.step_rad <= 0.0 {
            return None;
        }
        let k = ((self.unwrap(angle_rad) - self.angle_rad(0)) / self.step_rad).round();
        if self.turn {
            Some((k as isize).rem_euclid(self.n as isize) as usize)
        } else if k < 0.0 || k >= self.n as f64 {
            None
        } else {
            Some(k as usize)
        }
    }
}
