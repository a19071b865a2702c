//! What a model was trained on, so that it is never applied far outside it: the range of
//! every input, of the path length and speed, and the direction of travel. A corrector fitted
//! to 1.5 m forward runs has no answer for a 15 m run or a run driven backwards; it would
//! return a plausible-looking number, so such logs are refused (or, on request, flagged).

use odocal_dataset::Sample;
use serde::{Deserialize, Serialize};

/// The share of each input's training range by which it may lie outside it (runs like the
/// training runs but not among them still fit).
pub const INPUT_MARGIN: f64 = 0.25;
/// The share of the longest training run by which a run may be shorter or longer.
pub const LENGTH_MARGIN: f64 = 0.1;

/// The training domain recorded in model.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainingDomain {
    /// Smallest and largest value of each of the 18 inputs.
    pub input_min: Vec<f64>,
    /// Largest value of each input.
    pub input_max: Vec<f64>,
    /// Shortest and longest distance from start to raw odometry end, metres.
    pub end_distance_m: [f64; 2],
    /// Whether every training run ended ahead of its start (raw odometry x > 0).
    pub forward_only: bool,
}

impl TrainingDomain {
    /// The domain of a set of samples (None when there are none).
    pub fn of(samples: &[Sample]) -> Option<Self> {
        let first = samples.first()?;
        let n = first.inputs.len();
        let (mut lo, mut hi) = (vec![f64::INFINITY; n], vec![f64::NEG_INFINITY; n]);
        let mut path = [f64::INFINITY, f64::NEG_INFINITY];
        for s in samples {
            for (i, &v) in s.inputs.iter().enumerate().take(n) {
                lo[i] = lo[i].min(v);
                hi[i] = hi[i].max(v);
            }
            let d = s.raw_end_m[0].hypot(s.raw_end_m[1]);
            path = [path[0].min(d), path[1].max(d)];
        }
        Some(Self {
            input_min: lo,
            input_max: hi,
            end_distance_m: path,
            forward_only: samples.iter().all(|s| s.raw_end_m[0] > 0.0),
        })
    }

    /// Why a log with these inputs and raw end point lies outside the domain (each reason
    /// with its figures), or an empty list when it lies inside.
    pub fn outside(&self, inputs: &[f64], raw_end_m: [f64; 2]) -> Vec<String> {
        let mut why = Vec::new();
        let [p0, p1] = self.end_distance_m;
        let pm = LENGTH_MARGIN * p1 + INPUT_MARGIN * (p1 - p0);
        let d = raw_end_m[0].hypot(raw_end_m[1]);
        if !(d >= p0 - pm && d <= p1 + pm) {
            why.push(format!(
                "it ends {d:.3} m from its start (trained on {p0:.3}-{p1:.3} m)"
            ));
        }
        if self.forward_only && raw_end_m[0] <= 0.0 {
            why.push(format!(
                "the run ends {:.3} m behind its start (trained on forward runs only)",
                -raw_end_m[0]
            ));
        }
        for (i, &v) in inputs.iter().enumerate() {
            let (Some(&a), Some(&b)) = (self.input_min.get(i), self.input_max.get(i)) else {
                continue;
            };
            let m = INPUT_MARGIN * (b - a).abs().max(1e-3);
            if !(v >= a - m && v <= b + m) {
                why.push(format!("input {i} = {v:.4} (trained on {a:.4}-{b:.4})"));
                break;
            }
        }
        why
    }
}
