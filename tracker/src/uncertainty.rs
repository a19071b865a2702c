//! How well each pose is known: σx, σy, σθ of a fix.
//!
//! Two sources add up. Detection noise: the four corners' covariance is part independent per
//! corner and part from their four fitted sides ([`corner_covariance_from_sides`]; the mix in
//! `track.rs`), scaled to the noise seen, and carried through the planar pose fit by its
//! Jacobian (finite differences of [`planar_pose`] over the eight corner coordinates), so the
//! geometry of each view (distance, tilt, lens distortion at that place) shapes the result.
//! Calibration: the intrinsics' covariance from camera.json carried through the same fit by
//! finite differences over the intrinsic parameters. It is the same error in every frame (a
//! bias of the whole track at that place), but a user comparing poses with anything else
//! needs it in the error bar.
//!
//! The corner σ comes from the planar fits' own residuals: four corners against a square of
//! known size leave 8 − 3 = 5 degrees of freedom per frame, far too few for one frame alone,
//! so the tracker pools them over recent fixes (see `track.rs`), as the ratio of the residuals
//! to what [`expected_residual_px2`] expects of the corners' covariance.
//!
//! The edge refit's own covariance (grey-level residuals through its Jacobian, with the
//! correlation of corners that share a side) was tried as the corners' covariance, scaled by
//! the same residuals: it made position σ two to three times too small on synthetic truth,
//! since an error common to all four corners (a shift of the whole tag) leaves no residual.

use nalgebra::{DMatrix, Matrix3, Point2, SMatrix};
use odocal_calib::{CameraModel, FloorToCamera};
use odocal_core::{fit_rigid, wrap_angle, PoseSigma};

use crate::pose::{planar_pose, tag_model, PlanarPose};

/// Step of the finite differences over corner coordinates, pixels.
const CORNER_STEP_PX: f64 = 0.05;
/// Step of the finite differences over marker-plane coordinates, metres.
const FLOOR_STEP_M: f64 = 1e-6;

/// Differences of two poses as (x, y, θ), the heading wrapped.
fn delta(a: &PlanarPose, b: &PlanarPose) -> [f64; 3] {
    [
        a.pose.x_m - b.pose.x_m,
        a.pose.y_m - b.pose.y_m,
        wrap_angle(a.pose.theta_rad - b.pose.theta_rad),
    ]
}

/// Covariance of (x, y, θ) for corners of covariance `corner_cov_px2` (x0, y0, x1, y1, …).
///
/// The Jacobian is taken in two steps, each by finite differences: pixel → marker plane for
/// each corner on its own (2 × 2; the lens is undistorted 8 times, not 64), then the rigid fit
/// of the square to the four plane points (3 × 8, a closed form, cheap).
pub fn corner_covariance(
    camera: &CameraModel,
    floor: &FloorToCamera,
    corners_px: &[Point2<f64>; 4],
    tag_size_m: f64,
    marker_height_m: f64,
    corner_cov_px2: &SMatrix<f64, 8, 8>,
) -> Option<Matrix3<f64>> {
    let mut on_floor = [Point2::origin(); 4];
    let mut to_floor = SMatrix::<f64, 8, 8>::zeros();
    for (i, c) in corners_px.iter().enumerate() {
        let q = camera.pixel_to_floor(floor, c, marker_height_m)?;
        on_floor[i] = q;
        for axis in 0..2 {
            let mut p = *c;
            p[axis] += CORNER_STEP_PX;
            let d = (camera.pixel_to_floor(floor, &p, marker_height_m)? - q) / CORNER_STEP_PX;
            to_floor[(2 * i, 2 * i + axis)] = d.x;
            to_floor[(2 * i + 1, 2 * i + axis)] = d.y;
        }
    }
    let model = tag_model(tag_size_m);
    let base = fit_rigid(&model, &on_floor).ok()?.pose;
    let mut fit = SMatrix::<f64, 3, 8>::zeros();
    for k in 0..8 {
        let mut q = on_floor;
        q[k / 2][k % 2] += FLOOR_STEP_M;
        let p = fit_rigid(&model, &q).ok()?.pose;
        let d = [
            p.x_m - base.x_m,
            p.y_m - base.y_m,
            wrap_angle(p.theta_rad - base.theta_rad),
        ];
        for r in 0..3 {
            fit[(r, k)] = d[r] / FLOOR_STEP_M;
        }
    }
    let j = fit * to_floor;
    Some(j * corner_cov_px2 * j.transpose())
}

/// The covariance of four corners found as the intersections of four fitted sides, each side's
/// offset and angle independent, for a side offset σ of 1 pixel: a side fitted to pixels along
/// a length L has an angle σ of √12 / L per pixel of offset σ. An angle error moves a side's
/// two corners in opposite directions, so the corners are correlated: turns of the whole tag
/// (heading) are likelier, and shifts (position) less likely, than four independent corners
/// of the same spread would make them. Normalised to a mean variance of 1 per coordinate.
pub fn corner_covariance_from_sides(
    corners_px: &[Point2<f64>; 4],
    fitted_fraction: f64,
) -> SMatrix<f64, 8, 8> {
    // Side i runs from corner i to corner i + 1.
    let side = |i: usize| {
        let (a, b) = (corners_px[i], corners_px[(i + 1) % 4]);
        let len = (b - a).norm().max(1e-9);
        let u = (b - a) / len;
        (nalgebra::Vector2::new(-u.y, u.x), len)
    };
    // d corner / d (ρ_j, φ_j): corner i is on side i − 1 at +L/2 and on side i at −L/2.
    let mut jac = SMatrix::<f64, 8, 8>::zeros();
    let mut var = [0.0; 8];
    for i in 0..4 {
        let a = (i + 3) % 4;
        let (na, la) = side(a);
        let (nb, lb) = side(i);
        let n = nalgebra::Matrix2::new(na.x, na.y, nb.x, nb.y);
        let Some(inv) = n.try_inverse() else {
            return SMatrix::identity();
        };
        // Line j's normal displacement at arc position s is δρ_j + s δφ_j.
        for (col, (j, s)) in [(0, (a, 0.5 * la)), (1, (i, -0.5 * lb))] {
            let d_rho = inv.column(col).into_owned();
            jac.fixed_view_mut::<2, 1>(2 * i, 2 * j).copy_from(&d_rho);
            jac.fixed_view_mut::<2, 1>(2 * i, 2 * j + 1)
                .copy_from(&(d_rho * s));
        }
    }
    for j in 0..4 {
        let (_, len) = side(j);
        var[2 * j] = 1.0;
        var[2 * j + 1] = 12.0 / (fitted_fraction * len).powi(2);
    }
    let cov = jac * SMatrix::<f64, 8, 8>::from_diagonal(&var.into()) * jac.transpose();
    let mean = cov.trace() / 8.0;
    if mean.is_finite() && mean > 0.0 {
        cov / mean
    } else {
        SMatrix::identity()
    }
}

/// The expected sum of squared corner residuals of the planar fit (pixels²) if the corners
/// had covariance `corner_cov_px2`: tr(M Σ Mᵀ), M the projection onto what a square at
/// `pose` cannot explain (8 coordinates minus the 3 of the pose).
pub fn expected_residual_px2(
    camera: &CameraModel,
    floor: &FloorToCamera,
    pose: &odocal_core::Pose2,
    tag_size_m: f64,
    marker_height_m: f64,
    corner_cov_px2: &SMatrix<f64, 8, 8>,
) -> Option<f64> {
    let model = tag_model(tag_size_m);
    let project = |p: &odocal_core::Pose2| -> Option<[Point2<f64>; 4]> {
        let mut out = [Point2::origin(); 4];
        for (o, m) in out.iter_mut().zip(&model) {
            *o = camera.floor_to_pixel(floor, &p.transform_point(m), marker_height_m)?;
        }
        Some(out)
    };
    let base = project(pose)?;
    let mut a = SMatrix::<f64, 8, 3>::zeros();
    let steps = [1e-5, 1e-5, 1e-4];
    for k in 0..3 {
        let mut p = *pose;
        match k {
            0 => p.x_m += steps[0],
            1 => p.y_m += steps[1],
            _ => p.theta_rad += steps[2],
        }
        let moved = project(&p)?;
        for c in 0..4 {
            a[(2 * c, k)] = (moved[c].x - base[c].x) / steps[k];
            a[(2 * c + 1, k)] = (moved[c].y - base[c].y) / steps[k];
        }
    }
    let hat = a * (a.transpose() * a).try_inverse()? * a.transpose();
    let m = SMatrix::<f64, 8, 8>::identity() - hat;
    Some((m * corner_cov_px2 * m.transpose()).trace())
}

/// Covariance of (x, y, θ) from the intrinsics' covariance `cov` (in the order of
/// [`CameraModel::parameters`]); the floor pose is held fixed.
pub fn calibration_covariance(
    camera: &CameraModel,
    floor: &FloorToCamera,
    corners_px: &[Point2<f64>; 4],
    tag_size_m: f64,
    marker_height_m: f64,
    cov: &DMatrix<f64>,
) -> Option<Matrix3<f64>> {
    let p = camera.parameters();
    if cov.nrows() != p.len() || cov.ncols() != p.len() {
        return None;
    }
    let mut j = DMatrix::<f64>::zeros(3, p.len());
    for k in 0..p.len() {
        // A step of a tenth of the parameter's own σ (or a tiny absolute one) stays linear.
        let step = (0.1 * cov[(k, k)].max(0.0).sqrt()).max(1e-9 * (1.0 + p[k].abs()));
        let mut plus = p.clone();
        let mut minus = p.clone();
        plus[k] += step;
        minus[k] -= step;
        let a = planar_pose(
            &camera.with_parameters(&plus),
            floor,
            corners_px,
            tag_size_m,
            marker_height_m,
        )?;
        let b = planar_pose(
            &camera.with_parameters(&minus),
            floor,
            corners_px,
            tag_size_m,
            marker_height_m,
        )?;
        let d = delta(&a, &b);
        for r in 0..3 {
            j[(r, k)] = d[r] / (2.0 * step);
        }
    }
    let c = &j * cov * j.transpose();
    Some(Matrix3::from_fn(|r, k| c[(r, k)]))
}

/// The σ of a pose from its covariance.
pub fn sigma_of(cov: &Matrix3<f64>) -> PoseSigma {
    PoseSigma {
        x_m: cov[(0, 0)].max(0.0).sqrt(),
        y_m: cov[(1, 1)].max(0.0).sqrt(),
        theta_rad: cov[(2, 2)].max(0.0).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    use odocal_core::Pose2;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// The sides' corner covariance matches the scatter of corners intersected from sides
    /// drawn with independent offset and angle errors (a turned, uneven quadrilateral).
    #[test]
    fn side_covariance_matches_monte_carlo() {
        let corners = [
            Point2::new(100.0, 80.0),
            Point2::new(141.0, 86.0),
            Point2::new(135.0, 124.0),
            Point2::new(96.0, 119.0),
        ];
        let fitted = 0.76;
        let model = corner_covariance_from_sides(&corners, fitted);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let unit = Normal::new(0.0, 1.0).unwrap();
        let n = 40_000;
        let mut samples = Vec::with_capacity(n);
        for _ in 0..n {
            // Each side moved along its normal by δρ and turned by δφ about its midpoint.
            let lines: Vec<(Point2<f64>, nalgebra::Vector2<f64>)> = (0..4)
                .map(|i| {
                    let (a, b) = (corners[i], corners[(i + 1) % 4]);
                    let len = (b - a).norm();
                    let u = (b - a) / len;
                    let nrm = nalgebra::Vector2::new(-u.y, u.x);
                    let rho = unit.sample(&mut rng);
                    let phi = unit.sample(&mut rng) * 12f64.sqrt() / (fitted * len);
                    let mid = nalgebra::center(&a, &b) + nrm * rho;
                    (mid, nalgebra::Rotation2::new(phi) * u)
                })
                .collect();
            let mut x = nalgebra::SVector::<f64, 8>::zeros();
            for i in 0..4 {
                let (p, u) = lines[(i + 3) % 4];
                let (q, v) = lines[i];
                let cross = u.x * v.y - u.y * v.x;
                let d = q - p;
                let c = p + u * ((d.x * v.y - d.y * v.x) / cross);
                x[2 * i] = c.x - corners[i].x;
                x[2 * i + 1] = c.y - corners[i].y;
            }
            samples.push(x);
        }
        let mut cov = SMatrix::<f64, 8, 8>::zeros();
        for x in &samples {
            cov += x * x.transpose();
        }
        cov /= n as f64;
        let cov = cov / (cov.trace() / 8.0);
        let worst = (cov - model).abs().max();
        assert!(
            worst < 0.04,
            "largest difference {worst:.3}\n{cov:.3}\n{model:.3}"
        );
        // Corners that share a side are correlated: not the identity.
        assert!((model - SMatrix::<f64, 8, 8>::identity()).abs().max() > 0.2);
    }

    /// The propagated σ matches the scatter of poses fitted to corners with that noise.
    #[test]
    fn propagated_sigma_matches_monte_carlo() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0);
        let rot = UnitQuaternion::from_euler_angles(0.02, -0.015, 0.3)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let c = Vector3::new(0.1, -0.2, 2.2);
        let floor = FloorToCamera(Isometry3::from_parts(Translation3::from(-(rot * c)), rot));
        let pose = Pose2::new(0.6, 0.3, 0.4);
        let corners = tag_model(0.08).map(|m| {
            cam.floor_to_pixel(&floor, &pose.transform_point(&m), 0.08)
                .unwrap()
        });
        let iid = SMatrix::<f64, 8, 8>::identity() * 0.04;
        let s = sigma_of(&corner_covariance(&cam, &floor, &corners, 0.08, 0.08, &iid).unwrap());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.2).unwrap();
        let n = 4000;
        let (mut sx, mut sy, mut st) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let c = corners
                .map(|p| Point2::new(p.x + noise.sample(&mut rng), p.y + noise.sample(&mut rng)));
            let p = planar_pose(&cam, &floor, &c, 0.08, 0.08).unwrap();
            sx += (p.pose.x_m - pose.x_m).powi(2);
            sy += (p.pose.y_m - pose.y_m).powi(2);
            st += wrap_angle(p.pose.theta_rad - pose.theta_rad).powi(2);
        }
        let mc = [sx, sy, st].map(|v| (v / n as f64).sqrt());
        for (m, p) in mc.iter().zip([s.x_m, s.y_m, s.theta_rad]) {
            assert!(
                (m / p - 1.0).abs() < 0.05,
                "Monte Carlo {mc:?} vs propagated {s:?}"
            );
        }
    }
}
