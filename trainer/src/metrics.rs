//! Error metrics of end-point predictions.

use odocal_dataset::Sample;
use serde::{Deserialize, Serialize};

/// Metrics of a set of end-point predictions against the real end points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Mean squared error per coordinate, m^2: mean over samples and both coordinates of (y - t)^2.
    pub mse_m2: f64,
    /// The same in cm^2.
    pub mse_cm2: f64,
    /// The source's objective E = 1/2 sum_k sum_j (y_j^k - t_j^k)^2, m^2.
    pub half_sse_m2: f64,
    /// Mean relative end-point error |y - t| / path length (a fraction; x100 for %).
    pub rel_error: f64,
    /// Root mean square end-point distance error, m.
    pub rms_end_error_m: f64,
    /// Number of samples.
    pub n: usize,
}

impl Metrics {
    /// Metrics of `pred[i]` against `samples[i]`.
    pub fn of(samples: &[&Sample], pred: &[[f64; 2]]) -> Self {
        let n = samples.len().min(pred.len());
        let mut sse = 0.0;
        let mut rel = 0.0;
        for (s, p) in samples.iter().zip(pred) {
            let dx = p[0] - s.target_m[0];
            let dy = p[1] - s.target_m[1];
            let d2 = dx * dx + dy * dy;
            sse += d2;
            rel += d2.sqrt() / s.path_length_m;
        }
        let nf = n.max(1) as f64;
        let mse = sse / (2.0 * nf);
        Self {
            mse_m2: mse,
            mse_cm2: mse * 1e4,
            half_sse_m2: 0.5 * sse,
            rel_error: rel / nf,
            rms_end_error_m: (sse / nf).sqrt(),
            n,
        }
    }
}

/// Mean and sample standard deviation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanSd {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 for one value).
    pub sd: f64,
}

/// What a table's "±" spans, said under every table that prints [`MeanSd::shown`].
pub const SPREAD_NOTE: &str = "± is one standard deviation: over folds and restarts for epochs and training MSE, over restarts for the validation figures and Table 2 (each restart's held-out predictions of all folds pooled); a figure without ± did not vary (a deterministic method, or one restart)";

impl MeanSd {
    /// "mean ± sd" scaled by `scale` to `prec` decimals; the mean alone when the sd is 0 (one
    /// value, or a deterministic method's restarts), where "± 0.00" read as no uncertainty.
    pub fn shown(&self, scale: f64, prec: usize) -> String {
        if self.sd == 0.0 {
            format!("{:.p$}", self.mean * scale, p = prec)
        } else {
            format!(
                "{:.p$} ± {:.p$}",
                self.mean * scale,
                self.sd * scale,
                p = prec
            )
        }
    }

    /// Mean and sd of `v` (NaN mean for an empty slice).
    pub fn of(v: &[f64]) -> Self {
        let n = v.len();
        if n == 0 {
            return Self {
                mean: f64::NAN,
                sd: 0.0,
            };
        }
        let mean = v.iter().sum::<f64>() / n as f64;
        let sd = if n > 1 {
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Self { mean, sd }
    }
}
