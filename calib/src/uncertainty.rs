//! How well a calibration is known: the covariance of the intrinsic parameters (with the
//! board poses marginalised out) from the Jacobian of every corner's reprojection at the
//! optimum, and from it how uncertain the projection of a direction is, pixel by pixel over
//! the image (mrcal's "projection uncertainty"). Computed for every lens model alike from
//! odocal's own projection, which the tests check against OpenCV's.

use nalgebra::{DMatrix, Matrix2, Point2, Point3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::calibrate::Observation;
use crate::CameraModel;

/// The residuals and covariance of a calibration at its optimum.
#[derive(Debug, Clone)]
pub struct Fit {
    /// RMS reprojection error over all corners, pixels (OpenCV's definition: the root of the
    /// mean squared distance between detected and reprojected corners).
    pub rms_px: f64,
    /// The same per view, in input order.
    pub view_rms_px: Vec<f64>,
    /// Covariance of [`CameraModel::parameters`], the board poses marginalised out, scaled by
    /// the residual variance.
    pub covariance: DMatrix<f64>,
}

/// Pixel residuals of one view, two per point (u then v).
pub(crate) fn residuals(
    camera: &CameraModel,
    pose: &nalgebra::Isometry3<f64>,
    o: &Observation,
) -> Vec<f64> {
    let mut r = Vec::with_capacity(2 * o.object.len());
    for (p, x) in o.object.iter().zip(o.image) {
        match camera.project(&(pose * p)) {
            Some(q) => {
                r.push(q.x - x.x);
                r.push(q.y - x.y);
            }
            None => {
                r.push(f64::NAN);
                r.push(f64::NAN);
            }
        }
    }
    r
}

/// A pose moved by a small rotation `w` (radians, camera frame) and translation `t` (metres).
pub(crate) fn nudge(pose: &nalgebra::Isometry3<f64>, k: usize, h: f64) -> nalgebra::Isometry3<f64> {
    let mut p = *pose;
    if k < 3 {
        let mut w = Vector3::zeros();
        w[k] = h;
        p.rotation = UnitQuaternion::from_scaled_axis(w) * p.rotation;
        p.translation.vector = UnitQuaternion::from_scaled_axis(w) * p.translation.vector;
    } else {
        p.translation.vector[k - 3] += h;
    }
    p
}

/// Central-difference step for each intrinsic parameter: a ten-millionth of a focal length
/// for the pixel parameters, 1e-7 for the dimensionless coefficients.
pub(crate) fn steps(camera: &CameraModel) -> Vec<f64> {
    let f = camera.intrinsics.fx.abs().max(1.0);
    camera
        .parameters()
        .iter()
        .enumerate()
        .map(|(i, _)| if i < 4 { 1e-7 * f } else { 1e-7 })
        .collect()
}

/// Derivatives of a view's residuals with respect to the intrinsics (columns of `ji`) and its
/// own pose (columns of `jp`).
pub(crate) fn view_jacobians(
    camera: &CameraModel,
    o: &Observation,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let pose = o.pose.0;
    let n = 2 * o.object.len();
    let p0 = camera.parameters();
    let hs = steps(camera);
    let mut ji = DMatrix::zeros(n, p0.len());
    for (i, h) in hs.iter().enumerate() {
        let mut plus = p0.clone();
        let mut minus = p0.clone();
        plus[i] += h;
        minus[i] -= h;
        let rp = residuals(&camera.with_parameters(&plus), &pose, o);
        let rm = residuals(&camera.with_parameters(&minus), &pose, o);
        for r in 0..n {
            ji[(r, i)] = (rp[r] - rm[r]) / (2.0 * h);
        }
    }
    let mut jp = DMatrix::zeros(n, 6);
    let h = 1e-7;
    for k in 0..6 {
        let rp = residuals(camera, &nudge(&pose, k, h), o);
        let rm = residuals(camera, &nudge(&pose, k, -h), o);
        for r in 0..n {
            jp[(r, k)] = (rp[r] - rm[r]) / (2.0 * h);
        }
    }
    (ji, jp)
}

/// The residuals and the intrinsics' covariance at the optimum of a calibration.
///
/// With J = [Jᵢ Jₚ] the Jacobian of all residuals in the intrinsics and the poses, the
/// intrinsics' covariance is σ² (Aᵢᵢ − Σᵥ Bᵥ Cᵥ⁻¹ Bᵥᵀ)⁻¹ (the Schur complement of the poses,
/// one 6×6 block per view), with σ² the residual variance per coordinate.
pub fn covariance(camera: &CameraModel, observations: &[Observation]) -> Fit {
    let ni = camera.parameters().len();
    let mut schur = DMatrix::<f64>::zeros(ni, ni);
    let mut sum_sq = 0.0;
    let mut n_points = 0usize;
    let mut view_rms_px = Vec::with_capacity(observations.len());
    for o in observations {
        let r = residuals(camera, &o.pose.0, o);
        let ss: f64 = r.iter().map(|v| v * v).sum();
        let np = o.object.len().max(1);
        view_rms_px.push((ss / np as f64).sqrt());
        sum_sq += ss;
        n_points += o.object.len();
        let (ji, jp) = view_jacobians(camera, o);
        let a = ji.transpose() * &ji;
        let b = ji.transpose() * &jp;
        let c = jp.transpose() * &jp;
        schur += a;
        if let Some(ci) = c.try_inverse() {
            schur -= &b * ci * b.transpose();
        }
    }
    let dof = (2 * n_points)
        .saturating_sub(ni + 6 * observations.len())
        .max(1);
    let sigma2 = sum_sq / dof as f64;
    let covariance = bounded_pseudo_inverse(schur)
        .unwrap_or_else(|| DMatrix::from_element(ni, ni, f64::NAN))
        * sigma2;
    Fit {
        rms_px: (sum_sq / n_points.max(1) as f64).sqrt(),
        view_rms_px,
        covariance,
    }
}

/// How uncertain the projection of the direction `dir` (camera frame) is: one standard
/// deviation along the worst image direction, pixels, from the intrinsics' covariance.
pub fn projection_sigma_px(
    camera: &CameraModel,
    covariance: &DMatrix<f64>,
    dir: &Vector3<f64>,
) -> f64 {
    let p0 = camera.parameters();
    if covariance.nrows() != p0.len() {
        return f64::NAN;
    }
    let pt = Point3::from(*dir);
    let hs = steps(camera);
    let mut j = DMatrix::<f64>::zeros(2, p0.len());
    for (i, h) in hs.iter().enumerate() {
        let mut plus = p0.clone();
        let mut minus = p0.clone();
        plus[i] += h;
        minus[i] -= h;
        let (Some(a), Some(b)) = (
            camera.with_parameters(&plus).project(&pt),
            camera.with_parameters(&minus).project(&pt),
        ) else {
            return f64::NAN;
        };
        j[(0, i)] = (a.x - b.x) / (2.0 * h);
        j[(1, i)] = (a.y - b.y) / (2.0 * h);
    }
    let s = &j * covariance * j.transpose();
    let m = Matrix2::new(s[(0, 0)], s[(0, 1)], s[(1, 0)], s[(1, 1)]);
    worst_sigma(&m)
}

/// The square root of the largest eigenvalue of a 2x2 covariance: the standard deviation
/// along its worst direction (NaN if the matrix is not finite).
pub(crate) fn worst_sigma(m: &Matrix2<f64>) -> f64 {
    if !m.iter().all(|v| v.is_finite()) {
        return f64::NAN;
    }
    // Closed form for a symmetric 2x2: no iteration that a bad matrix could keep spinning.
    let (a, b, d) = (m[(0, 0)], 0.5 * (m[(0, 1)] + m[(1, 0)]), m[(1, 1)]);
    let worst = 0.5 * (a + d) + (0.25 * (a - d).powi(2) + b * b).sqrt();
    worst.max(0.0).sqrt()
}

/// The pseudo-inverse of a normal matrix, or `None` if it holds non-finite values or its SVD
/// does not converge (nalgebra's SVD would otherwise iterate forever on NaN).
fn bounded_pseudo_inverse(m: DMatrix<f64>) -> Option<DMatrix<f64>> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    nalgebra::SVD::try_new(m, true, true, f64::EPSILON, 10_000)?
        .pseudo_inverse(1e-300)
        .ok()
}

/// Projection uncertainty over the image on a grid of cells: the σ of each cell centre.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UncertaintyMap {
    /// Side of a cell, pixels.
    pub cell_px: u32,
    /// Cells across.
    pub cols: u32,
    /// Cells down.
    pub rows: u32,
    /// Worst-direction σ of the projection at each cell centre, pixels, row by row.
    pub sigma_px: Vec<f64>,
}

impl UncertaintyMap {
    /// The map of `camera` with `covariance` on cells of `cell_px`.
    pub fn new(camera: &CameraModel, covariance: &DMatrix<f64>, cell_px: u32) -> Self {
        let cell_px = cell_px.max(1);
        let cols = camera.width.div_ceil(cell_px);
        let rows = camera.height.div_ceil(cell_px);
        let mut sigma_px = Vec::with_capacity((cols * rows) as usize);
        for r in 0..rows {
            for c in 0..cols {
                let pix = Self::centre(camera, cell_px, c, r);
                let u = camera.unproject(&pix);
                sigma_px.push(projection_sigma_px(
                    camera,
                    covariance,
                    &Vector3::new(u.x, u.y, 1.0),
                ));
            }
        }
        Self {
            cell_px,
            cols,
            rows,
            sigma_px,
        }
    }

    /// The pixel at the centre of cell (c, r), clamped into the image.
    pub fn centre(camera: &CameraModel, cell_px: u32, c: u32, r: u32) -> Point2<f64> {
        let x = ((c as f64 + 0.5) * cell_px as f64).min(camera.width as f64 - 1.0);
        let y = ((r as f64 + 0.5) * cell_px as f64).min(camera.height as f64 - 1.0);
        Point2::new(x, y)
    }

    /// The largest σ on the map, pixels.
    pub fn max_px(&self) -> f64 {
        self.sigma_px
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max)
    }

    /// The median σ on the map, pixels (`None` when no cell has a finite σ).
    pub fn median_px(&self) -> Option<f64> {
        let mut v: Vec<f64> = self
            .sigma_px
            .iter()
            .copied()
            .filter(|x| x.is_finite())
            .collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied()
    }
}

/// A projection σ for people, pixels with `decimals` places, or "more than N px
/// (unbounded)" from `side_px` (the image's larger side) up: where a lens model turns over or
/// its parameters are barely fixed, the covariance gives σ of millions of pixels ("largest
/// 1737648756.293 px" for pinhole5 fixed on a wide rational lens), and a σ beyond the image
/// itself says only that the direction is not known there.
pub fn far_px(px: f64, side_px: u32, decimals: usize) -> String {
    if px < f64::from(side_px) {
        format!("{px:.decimals$} px")
    } else {
        format!("more than {side_px} px, the image's size (unbounded)")
    }
}
