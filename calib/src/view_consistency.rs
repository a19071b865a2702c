//! Whether every view agrees with the others on the camera: each view's own focal length
//! and principal point, fitted from its corners alone with the distortion of the calibration
//! of the other views, against that calibration. A lens zoomed between photos, or photos turned 180°
//! by a viewer (which mirrors the principal point), fit one camera together within a
//! hundredth of a pixel of the held-out error, while putting fx 11σ off; the views' own
//! intrinsics tell them apart by tens of σ.

use nalgebra::{DMatrix, DVector, Matrix3};

use crate::calibrate::Observation;
use crate::uncertainty::{nudge, residuals};
use crate::CameraModel;

/// One view's disagreement with the calibration of all the views.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewIntrinsics {
    /// The view's image.
    pub image: String,
    /// Its focal length over the calibration's, minus one.
    pub focal_share: f64,
    /// Its principal point minus the calibration's, pixels.
    pub dcx_px: f64,
    /// The same down the image, pixels.
    pub dcy_px: f64,
    /// One standard deviation of each of the three differences (the view's own fit and the
    /// calibration's, together).
    pub sigma: [f64; 3],
    /// The differences' chi-square on their joint covariance (3 degrees of freedom).
    pub chi2: f64,
}

/// How far the views' chi-squares summed may exceed their degrees of freedom (3 a view), in
/// standard deviations of that sum (√(6n)) before the views are said to disagree: one
/// camera's views sum to about their degrees of freedom (10 views of `synth calib`: 20.6 over
/// 30; 14: 40.7 over 42), half the views zoomed 5 % to 134.5 over 30, half turned 180° to 467.
pub const EXCESS_SIGMAS: f64 = 5.0;

/// A view whose own chi-square exceeds this is named among the disagreeing ones (once in
/// ten thousand views of one camera by chance).
pub const VIEW_CHI2: f64 = 21.1;

/// Whether chi-squares `chi2` of views (3 degrees of freedom each) sum to more than one
/// camera's views do by chance.
pub fn disagree(views: &[ViewIntrinsics]) -> bool {
    let n = views.len() as f64;
    let sum: f64 = views.iter().map(|v| v.chi2).sum();
    views.len() >= 4 && sum > 3.0 * n + EXCESS_SIGMAS * (6.0 * n).sqrt()
}

/// Each view's focal length (one scale for fx and fy) and principal point fitted from its
/// corners with its own pose, the calibration's distortion held (Levenberg–Marquardt from the
/// calibration's pose), against `camera` whose parameters have `covariance`; `sigma2` is the
/// residual variance per pixel coordinate. Views whose fit does not converge are left out.
pub fn view_intrinsics(
    camera: &CameraModel,
    covariance: &DMatrix<f64>,
    sigma2: f64,
    images: &[String],
    observations: &[Observation],
) -> Vec<ViewIntrinsics> {
    let k = camera.intrinsics;
    // (fx, fy, cx, cy) to (focal share, cx, cy).
    let t = DMatrix::from_row_slice(
        3,
        4,
        &[
            0.5 / k.fx,
            0.5 / k.fy,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
        ],
    );
    let c4 = if covariance.nrows() >= 4 {
        covariance.view((0, 0), (4, 4)).into_owned()
    } else {
        return vec![];
    };
    let cal3 = &t * c4 * t.transpose();
    let params = camera.parameters();
    let full = covariance.nrows() == params.len() && covariance.ncols() == params.len();
    images
        .iter()
        .zip(observations)
        .filter_map(|(image, o)| {
            let (d, cov, along) = fit_view(camera, o, sigma2)?;
            // The calibration's uncertainty as it moves this view's fit: all its parameters,
            // the distortion too. A small board in the image's corner is fitted through the
            // distortion there, which the other views may fix loosely; counting only the
            // focal length's and centre's σ named such an ordinary view as disagreeing (χ²
            // 117 over 20 views where 42 ± 9 is chance).
            let c = cov
                + if full {
                    &along * covariance * along.transpose()
                } else {
                    cal3.clone()
                };
            let ci = c.clone().try_inverse()?;
            let chi2 = (d.transpose() * ci * &d)[(0, 0)];
            chi2.is_finite().then(|| ViewIntrinsics {
                image: image.clone(),
                focal_share: d[0],
                dcx_px: d[1],
                dcy_px: d[2],
                sigma: [
                    c[(0, 0)].max(0.0).sqrt(),
                    c[(1, 1)].max(0.0).sqrt(),
                    c[(2, 2)].max(0.0).sqrt(),
                ],
                chi2,
            })
        })
        .collect()
}

/// `camera` with its focal lengths scaled by `1 + s` and its principal point moved.
fn moved(camera: &CameraModel, s: f64, dcx: f64, dcy: f64) -> CameraModel {
    let mut c = *camera;
    c.intrinsics.fx *= 1.0 + s;
    c.intrinsics.fy *= 1.0 + s;
    c.intrinsics.cx += dcx;
    c.intrinsics.cy += dcy;
    c
}

/// One view's (focal share, dcx, dcy) and their covariance: fitted by Levenberg–Marquardt
/// (`odocal_core::lsq`) with the view's pose, which starts at the calibration's; the
/// covariance from the Jacobian at the optimum, the pose marginalised out, with the view's
/// own corner noise when it is beyond chance above `sigma2` (a small board's corners are
/// noisier than the calibration's average). Also how the three move with `camera`'s
/// parameters ([`CameraModel::parameters`]), 3 by their count, to first order.
fn fit_view(
    camera: &CameraModel,
    o: &Observation,
    sigma2: f64,
) -> Option<(DVector<f64>, DMatrix<f64>, DMatrix<f64>)> {
    // Parameters: the focal share, the principal point's move, then the pose's six nudges.
    let at = |p: &[f64]| {
        let pose = (0..6).fold(o.pose.0, |pose, k| nudge(&pose, k, p[3 + k]));
        residuals(&moved(camera, p[0], p[1], p[2]), &pose, o)
    };
    let (x, report) = odocal_core::lsq::minimize(&at, vec![0.0; 9], 100);
    if !report.termination.was_successful() {
        return None;
    }
    // Central differences, each step small against what the parameter moves a corner by.
    let steps = [1e-7, 1e-4, 1e-4, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7];
    let r0 = at(&x);
    let mut j = DMatrix::<f64>::zeros(r0.len(), 9);
    for (c, h) in steps.iter().enumerate() {
        let (mut a, mut b) = (x.clone(), x.clone());
        a[c] += h;
        b[c] -= h;
        for (r, (ra, rb)) in at(&a).iter().zip(at(&b)).enumerate() {
            j[(r, c)] = (ra - rb) / (2.0 * h);
        }
    }
    if !j.iter().all(|v| v.is_finite()) {
        return None;
    }
    let inv = (j.transpose() * &j).try_inverse()?;
    let finite: Vec<f64> = r0.iter().copied().filter(|v| v.is_finite()).collect();
    let dof = finite.len().saturating_sub(9).max(1) as f64;
    let own_var = finite.iter().map(|v| v * v).sum::<f64>() / dof;
    let sigma2 = if own_var > (1.0 + 3.1 * (2.0 / dof).sqrt()) * sigma2 {
        own_var
    } else {
        sigma2
    };
    let cov: Matrix3<f64> = inv.fixed_view::<3, 3>(0, 0).into_owned() * sigma2;
    // The camera's parameters nudged with the view's fit held: the fit's move is
    // −(JᵀJ)⁻¹Jᵀ times the corners' move.
    let params = camera.parameters();
    let pose = (0..6).fold(o.pose.0, |pose, k| nudge(&pose, k, x[3 + k]));
    let mut g = DMatrix::<f64>::zeros(r0.len(), params.len());
    for c in 0..params.len() {
        let h = 1e-6 * (1.0 + params[c].abs());
        let (mut a, mut b) = (params.clone(), params.clone());
        a[c] += h;
        b[c] -= h;
        let at_params = |q: &[f64]| {
            residuals(
                &moved(&camera.with_parameters(q), x[0], x[1], x[2]),
                &pose,
                o,
            )
        };
        for (r, (ra, rb)) in at_params(&a).iter().zip(at_params(&b)).enumerate() {
            g[(r, c)] = (ra - rb) / (2.0 * h);
        }
    }
    if !g.iter().all(|v| v.is_finite()) {
        return None;
    }
    let along = -(&inv * j.transpose() * g).rows(0, 3).into_owned();
    Some((
        DVector::from_column_slice(&x[..3]),
        DMatrix::from_iterator(3, 3, cov.iter().copied()),
        along,
    ))
}
