use nalgebra::{Point2, Vector2};
use thiserror::Error;

use crate::Pose2;

/// Why a 2-D point-set fit could not be computed.
#[derive(Debug, Error, PartialEq)]
pub enum FitError {
    /// The two point lists differ in length.
    #[error("point lists differ in length ({0} vs {1})")]
    LengthMismatch(usize, usize),
    /// Fewer than two point pairs: the rotation is undetermined.
    #[error("need at least 2 point pairs, got {0}")]
    TooFewPoints(usize),
    /// All source points coincide: the rotation is undetermined.
    #[error("points are degenerate (all coincide)")]
    Degenerate,
}

/// A least-squares rigid fit (rotation + translation, no scale, no reflection).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidFit {
    /// The pose that maps source points onto target points: target ≈ pose · source.
    pub pose: Pose2,
    /// Root-mean-square residual distance after the fit, in the target's units.
    pub rms: f64,
}

/// A least-squares 2-D Helmert (similarity) transform: target ≈ scale · R · source + t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Helmert2 {
    /// Rotation and translation part.
    pub pose: Pose2,
    /// Isotropic scale factor (1 for a perfect rigid match).
    pub scale: f64,
    /// Root-mean-square residual distance after the fit.
    pub rms: f64,
}

impl Helmert2 {
    /// Applies the transform to a source point.
    pub fn apply(&self, p: &Point2<f64>) -> Point2<f64> {
        let iso = self.pose.isometry();
        (iso.rotation * (p.coords * self.scale) + iso.translation.vector).into()
    }
}

struct Moments {
    src_mean: Vector2<f64>,
    dst_mean: Vector2<f64>,
    /// sum of (a·b) and (a×b) over centred pairs: cos and sin parts of the rotation.
    dot: f64,
    cross: f64,
    src_var: f64,
}

fn moments(src: &[Point2<f64>], dst: &[Point2<f64>]) -> Result<Moments, FitError> {
    if src.len() != dst.len() {
        return Err(FitError::LengthMismatch(src.len(), dst.len()));
    }
    if src.len() < 2 {
        return Err(FitError::TooFewPoints(src.len()));
    }
    let n = src.len() as f64;
    let src_mean = src.iter().map(|p| p.coords).sum::<Vector2<f64>>() / n;
    let dst_mean = dst.iter().map(|p| p.coords).sum::<Vector2<f64>>() / n;
    let (mut dot, mut cross, mut src_var) = (0.0, 0.0, 0.0);
    for (s, d) in src.iter().zip(dst) {
        let a = s.coords - src_mean;
        let b = d.coords - dst_mean;
        dot += a.dot(&b);
        cross += a.x * b.y - a.y * b.x;
        src_var += a.norm_squared();
    }
    if src_var <= f64::EPSILON * n {
        return Err(FitError::Degenerate);
    }
    Ok(Moments {
        src_mean,
        dst_mean,
        dot,
        cross,
        src_var,
    })
}

fn finish(m: &Moments, scale: f64, src: &[Point2<f64>], dst: &[Point2<f64>]) -> (Pose2, f64) {
    let theta = m.cross.atan2(m.dot);
    let (s, c) = theta.sin_cos();
    let rotated_mean = Vector2::new(
        c * m.src_mean.x - s * m.src_mean.y,
        s * m.src_mean.x + c * m.src_mean.y,
    );
    let t = m.dst_mean - rotated_mean * scale;
    let pose = Pose2::new(t.x, t.y, theta);
    let iso = pose.isometry();
    let sq: f64 = src
        .iter()
        .zip(dst)
        .map(|(p, q)| {
            ((iso.rotation * (p.coords * scale) + iso.translation.vector) - q.coords).norm_squared()
        })
        .sum();
    (pose, (sq / src.len() as f64).sqrt())
}

/// Least-squares rigid transform (closed form) mapping `src` onto `dst`.
pub fn fit_rigid(src: &[Point2<f64>], dst: &[Point2<f64>]) -> Result<RigidFit, FitError> {
    let m = moments(src, dst)?;
    let (pose, rms) = finish(&m, 1.0, src, dst);
    Ok(RigidFit { pose, rms })
}

/// Least-squares Helmert (similarity) transform mapping `src` onto `dst`.
pub fn fit_helmert(src: &[Point2<f64>], dst: &[Point2<f64>]) -> Result<Helmert2, FitError> {
    let m = moments(src, dst)?;
    let scale = m.dot.hypot(m.cross) / m.src_var;
    let (pose, rms) = finish(&m, scale, src, dst);
    Ok(Helmert2 { pose, scale, rms })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts() -> Vec<Point2<f64>> {
        vec![
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.2),
            Point2::new(0.3, 2.0),
            Point2::new(-1.5, 0.7),
        ]
    }

    #[test]
    fn rigid_recovers_known_pose() {
        let truth = Pose2::new(2.0, -1.0, 2.5);
        let src = pts();
        let dst: Vec<_> = src.iter().map(|p| truth.transform_point(p)).collect();
        let fit = fit_rigid(&src, &dst).unwrap();
        assert!((fit.pose.x_m - 2.0).abs() < 1e-12);
        assert!((fit.pose.y_m + 1.0).abs() < 1e-12);
        assert!((fit.pose.theta_rad - 2.5).abs() < 1e-12);
        assert!(fit.rms < 1e-12);
    }

    #[test]
    fn helmert_recovers_scale() {
        let truth = Pose2::new(0.5, 0.1, -0.4);
        let src = pts();
        let dst: Vec<_> = src
            .iter()
            .map(|p| truth.isometry().rotation * (p.coords * 1.01) + Vector2::new(0.5, 0.1))
            .map(Point2::from)
            .collect();
        let h = fit_helmert(&src, &dst).unwrap();
        assert!((h.scale - 1.01).abs() < 1e-12);
        assert!((h.pose.theta_rad + 0.4).abs() < 1e-12);
        assert!((h.apply(&src[2]) - dst[2]).norm() < 1e-12);
    }

    #[test]
    fn rejects_bad_input() {
        let p = pts();
        assert_eq!(fit_rigid(&p[..1], &p[..1]), Err(FitError::TooFewPoints(1)));
        assert_eq!(fit_rigid(&p, &p[..2]), Err(FitError::LengthMismatch(4, 2)));
        let same = vec![Point2::new(1.0, 1.0); 3];
        assert_eq!(fit_rigid(&same, &same), Err(FitError::Degenerate));
    }
}
