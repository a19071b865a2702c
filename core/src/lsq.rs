//! Least squares with a numerical Jacobian through the `levenberg-marquardt` crate, for fits
//! whose residuals are easier to compute than to differentiate (chained dead reckoning).

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, MinimizationReport};
use nalgebra::{DMatrix, DVector, Dyn, Owned};

/// A problem given by its residual function of the parameters.
struct Numeric<'a> {
    f: &'a (dyn Fn(&[f64]) -> Vec<f64> + Sync),
    p: Vec<f64>,
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Numeric<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;
    fn set_params(&mut self, x: &DVector<f64>) {
        self.p = x.iter().copied().collect();
    }
    fn params(&self) -> DVector<f64> {
        DVector::from_column_slice(&self.p)
    }
    fn residuals(&self) -> Option<DVector<f64>> {
        let r = (self.f)(&self.p);
        r.iter()
            .all(|v| v.is_finite())
            .then(|| DVector::from_vec(r))
    }
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        use rayon::prelude::*;
        // Central differences, one parameter per task.
        let cols: Vec<Vec<f64>> = (0..self.p.len())
            .into_par_iter()
            .map(|c| {
                let h = 1e-6 * (1.0 + self.p[c].abs());
                let mut a = self.p.clone();
                let mut b = self.p.clone();
                a[c] += h;
                b[c] -= h;
                let (ra, rb) = ((self.f)(&a), (self.f)(&b));
                ra.iter()
                    .zip(&rb)
                    .map(|(x, y)| (x - y) / (2.0 * h))
                    .collect()
            })
            .collect();
        let m = cols.first().map_or(0, Vec::len);
        let j = DMatrix::from_fn(m, cols.len(), |r, c| cols[c][r]);
        j.iter().all(|v| v.is_finite()).then_some(j)
    }
}

/// Minimises the sum of squares of `f` from `p0`; the parameters found and the crate's report.
pub fn minimize(
    f: &(dyn Fn(&[f64]) -> Vec<f64> + Sync),
    p0: Vec<f64>,
    patience: usize,
) -> (Vec<f64>, MinimizationReport<f64>) {
    let (problem, report) = LevenbergMarquardt::new()
        .with_patience(patience)
        .minimize(Numeric { f, p: p0 });
    (problem.p, report)
}
