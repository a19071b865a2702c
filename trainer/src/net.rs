//! The two-layer perceptron n-k-2: sigmoid hidden layer, linear outputs, with
//! the input/output normalisation stored beside the weights.

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Affine normalisation per column: `normalised = (value - offset) * scale`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    /// Per-column offset (the training mean), in the column's units.
    pub offset: Vec<f64>,
    /// Per-column scale (1 / training standard deviation; 0 for a constant column).
    pub scale: Vec<f64>,
}

impl Normalisation {
    /// Z-score normalisation fitted to the rows of `data` (each row one sample).
    pub fn fit(rows: &[&[f64]]) -> Self {
        let n = rows.first().map_or(0, |r| r.len());
        let count = rows.len().max(1) as f64;
        let mut offset = vec![0.0; n];
        let mut scale = vec![0.0; n];
        for c in 0..n {
            let mean = rows.iter().map(|r| r[c]).sum::<f64>() / count;
            let var = rows.iter().map(|r| (r[c] - mean).powi(2)).sum::<f64>() / count;
            let sd = var.sqrt();
            offset[c] = mean;
            // A constant column carries no information: it is mapped to 0.
            scale[c] = if sd > 1e-12 * (1.0 + mean.abs()) {
                1.0 / sd
            } else {
                0.0
            };
        }
        Self { offset, scale }
    }

    /// Maps a raw value of column `c` to normalised units.
    pub fn forward(&self, c: usize, v: f64) -> f64 {
        (v - self.offset[c]) * self.scale[c]
    }

    /// Maps a normalised value of column `c` back to raw units (needs a non-zero scale).
    pub fn inverse(&self, c: usize, v: f64) -> f64 {
        if self.scale[c] == 0.0 {
            self.offset[c]
        } else {
            self.offset[c] + v / self.scale[c]
        }
    }
}

/// Weights of an n-k-m perceptron; `w1` is k x n, `w2` is m x k (row-major in files).
#[derive(Debug, Clone, PartialEq)]
pub struct Perceptron {
    /// Hidden-layer weights, k x n.
    pub w1: DMatrix<f64>,
    /// Hidden-layer biases, k.
    pub b1: DVector<f64>,
    /// Output weights, m x k.
    pub w2: DMatrix<f64>,
    /// Output biases, m.
    pub b2: DVector<f64>,
}

/// The logistic sigmoid.
#[inline]
pub fn sigmoid(a: f64) -> f64 {
    1.0 / (1.0 + (-a).exp())
}

impl Perceptron {
    /// Number of trainable parameters of an n-k-m net: k(n+1) + m(k+1) (21k+2 for 18-k-2).
    pub fn n_params_for(n_in: usize, hidden: usize, n_out: usize) -> usize {
        hidden * (n_in + 1) + n_out * (hidden + 1)
    }

    /// Nguyen–Widrow initialisation of the hidden layer, small uniform output weights.
    pub fn init(n_in: usize, hidden: usize, n_out: usize, rng: &mut ChaCha8Rng) -> Self {
        let beta = 0.7 * (hidden as f64).powf(1.0 / n_in.max(1) as f64);
        let mut w1 = DMatrix::from_fn(hidden, n_in, |_, _| rng.gen_range(-1.0..1.0));
        for mut row in w1.row_iter_mut() {
            let norm = row.norm();
            if norm > 0.0 {
                row *= beta / norm;
            }
        }
        let b1 = DVector::from_fn(hidden, |_, _| rng.gen_range(-beta..beta));
        let lim = 1.0 / (hidden as f64).sqrt();
        let w2 = DMatrix::from_fn(n_out, hidden, |_, _| rng.gen_range(-lim..lim));
        let b2 = DVector::zeros(n_out);
        Self { w1, b1, w2, b2 }
    }

    /// Number of inputs.
    pub fn n_in(&self) -> usize {
        self.w1.ncols()
    }

    /// Number of hidden neurons.
    pub fn hidden(&self) -> usize {
        self.w1.nrows()
    }

    /// Number of outputs.
    pub fn n_out(&self) -> usize {
        self.w2.nrows()
    }

    /// Number of trainable parameters.
    pub fn n_params(&self) -> usize {
        Self::n_params_for(self.n_in(), self.hidden(), self.n_out())
    }

    /// Flattens the parameters: w1 (row-major), b1, w2 (row-major), b2.
    pub fn to_params(&self) -> DVector<f64> {
        let mut p = Vec::with_capacity(self.n_params());
        for r in 0..self.hidden() {
            p.extend(self.w1.row(r).iter());
        }
        p.extend(self.b1.iter());
        for r in 0..self.n_out() {
            p.extend(self.w2.row(r).iter());
        }
        p.extend(self.b2.iter());
        DVector::from_vec(p)
    }

    /// Loads parameters in the order of [`Perceptron::to_params`].
    pub fn set_params(&mut self, p: &DVector<f64>) {
        let (n, k, m) = (self.n_in(), self.hidden(), self.n_out());
        let mut i = 0;
        for r in 0..k {
            for c in 0..n {
                self.w1[(r, c)] = p[i];
                i += 1;
            }
        }
        for r in 0..k {
            self.b1[r] = p[i];
            i += 1;
        }
        for r in 0..m {
            for c in 0..k {
                self.w2[(r, c)] = p[i];
                i += 1;
            }
        }
        for r in 0..m {
            self.b2[r] = p[i];
            i += 1;
        }
    }

    /// Whether parameter `i` (flat order) is a weight rather than a bias (for weight decay).
    pub fn is_weight(&self, i: usize) -> bool {
        let (n, k, m) = (self.n_in(), self.hidden(), self.n_out());
        let w1_end = k * n;
        let b1_end = w1_end + k;
        let w2_end = b1_end + m * k;
        i < w1_end || (i >= b1_end && i < w2_end)
    }

    /// Hidden activations for one normalised input row.
    fn hidden_out(&self, x: &[f64], h: &mut [f64]) {
        for (j, hj) in h.iter_mut().enumerate() {
            let mut a = self.b1[j];
            for (i, xi) in x.iter().enumerate() {
                a += self.w1[(j, i)] * xi;
            }
            *hj = sigmoid(a);
        }
    }

    /// Output for one normalised input row, in normalised output units.
    pub fn forward(&self, x: &[f64], y: &mut [f64]) {
        let mut h = vec![0.0; self.hidden()];
        self.hidden_out(x, &mut h);
        for (o, yo) in y.iter_mut().enumerate() {
            let mut s = self.b2[o];
            for (j, hj) in h.iter().enumerate() {
                s += self.w2[(o, j)] * hj;
            }
            *yo = s;
        }
    }

    /// Residuals `y - t` for all rows (sample-major: sample s, output o at s*m + o)
    /// and, if `jac` is given, their Jacobian with respect to the flat parameters,
    /// stored column-major with leading dimension `ld` (>= rows) as `(slice, ld)`.
    pub fn residuals_and_jacobian(
        &self,
        xs: &DMatrix<f64>,
        ts: &DMatrix<f64>,
        res: &mut [f64],
        mut jac: Option<(&mut [f64], usize)>,
    ) {
        let (n, k, m) = (self.n_in(), self.hidden(), self.n_out());
        let b1_off = k * n;
        let w2_off = b1_off + k;
        let b2_off = w2_off + m * k;
        let mut h = vec![0.0; k];
        let mut x = vec![0.0; n];
        for s in 0..xs.nrows() {
            for (i, xi) in x.iter_mut().enumerate() {
                *xi = xs[(s, i)];
            }
            self.hidden_out(&x, &mut h);
            for o in 0..m {
                let mut y = self.b2[o];
                for (j, hj) in h.iter().enumerate() {
                    y += self.w2[(o, j)] * hj;
                }
                let row = s * m + o;
                res[row] = y - ts[(s, o)];
                if let Some((jac, ld)) = jac.as_mut() {
                    let ld = *ld;
                    let mut put = |col: usize, v: f64| jac[col * ld + row] = v;
                    for (j, hj) in h.iter().enumerate() {
                        let d = self.w2[(o, j)] * hj * (1.0 - hj);
                        for (i, xi) in x.iter().enumerate() {
                            put(j * n + i, d * xi);
                        }
                        put(b1_off + j, d);
                        put(w2_off + o * k + j, *hj);
                    }
                    for oo in 0..m {
                        // Outputs other than `o` do not depend on this output's weights.
                        if oo != o {
                            for j in 0..k {
                                put(w2_off + oo * k + j, 0.0);
                            }
                        }
                        put(b2_off + oo, if oo == o { 1.0 } else { 0.0 });
                    }
                }
            }
        }
    }
}

impl Perceptron {
    /// Half the sum of squared residuals, E = 1/2 sum (y - t)^2, and its gradient
    /// with respect to the flat parameters (back-propagation).
    pub fn error_and_gradient(&self, xs: &DMatrix<f64>, ts: &DMatrix<f64>) -> (f64, DVector<f64>) {
        let (n, k, m) = (self.n_in(), self.hidden(), self.n_out());
        let b1_off = k * n;
        let w2_off = b1_off + k;
        let b2_off = w2_off + m * k;
        let mut g = DVector::zeros(self.n_params());
        let mut e = 0.0;
        let mut h = vec![0.0; k];
        let mut x = vec![0.0; n];
        let mut delta_out = vec![0.0; m];
        for s in 0..xs.nrows() {
            for (i, xi) in x.iter_mut().enumerate() {
                *xi = xs[(s, i)];
            }
            self.hidden_out(&x, &mut h);
            for (o, d) in delta_out.iter_mut().enumerate() {
                let mut y = self.b2[o];
                for (j, hj) in h.iter().enumerate() {
                    y += self.w2[(o, j)] * hj;
                }
                *d = y - ts[(s, o)];
                e += 0.5 * *d * *d;
                g[b2_off + o] += *d;
                for (j, hj) in h.iter().enumerate() {
                    g[w2_off + o * k + j] += *d * hj;
                }
            }
            for j in 0..k {
                let back: f64 = (0..m).map(|o| delta_out[o] * self.w2[(o, j)]).sum();
                let dj = back * h[j] * (1.0 - h[j]);
                g[b1_off + j] += dj;
                for (i, xi) in x.iter().enumerate() {
                    g[j * n + i] += dj * xi;
                }
            }
        }
        (e, g)
    }
}
