use nalgebra::{Isometry2, Point2, Vector2};
use serde::{Deserialize, Serialize};

/// Wraps an angle in radians to (-pi, pi].
pub fn wrap_angle(a_rad: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    let mut w = a_rad.rem_euclid(two_pi);
    if w > std::f64::consts::PI {
        w -= two_pi;
    }
    w
}

/// A planar pose: position in metres and heading in radians (counter-clockwise
/// from the frame's x axis). As a transform it maps points from the body frame
/// into the frame the pose is expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Pose2 {
    /// x position, metres.
    pub x_m: f64,
    /// y position, metres.
    pub y_m: f64,
    /// heading, radians, counter-clockwise positive.
    pub theta_rad: f64,
}

impl Pose2 {
    /// Builds a pose from x, y in metres and heading in radians.
    pub fn new(x_m: f64, y_m: f64, theta_rad: f64) -> Self {
        Self {
            x_m,
            y_m,
            theta_rad,
        }
    }

    /// The pose as a nalgebra isometry (body to parent frame).
    pub fn isometry(&self) -> Isometry2<f64> {
        Isometry2::new(Vector2::new(self.x_m, self.y_m), self.theta_rad)
    }

    /// Builds a pose from a nalgebra isometry (body to parent frame).
    pub fn from_isometry(iso: &Isometry2<f64>) -> Self {
        Self::new(
            iso.translation.vector.x,
            iso.translation.vector.y,
            iso.rotation.angle(),
        )
    }

    /// Position as a point, metres.
    pub fn position(&self) -> Point2<f64> {
        Point2::new(self.x_m, self.y_m)
    }

    /// Maps a point given in this pose's body frame into the parent frame.
    pub fn transform_point(&self, p_body: &Point2<f64>) -> Point2<f64> {
        self.isometry() * p_body
    }

    /// Composition: `self` then `other` expressed in self's body frame.
    pub fn compose(&self, other: &Pose2) -> Pose2 {
        Pose2::from_isometry(&(self.isometry() * other.isometry()))
    }

    /// The inverse pose (parent frame seen from the body frame).
    pub fn inverse(&self) -> Pose2 {
        Pose2::from_isometry(&self.isometry().inverse())
    }

    /// Linear interpolation from `self` (w = 0) to `other` (w = 1); w outside [0, 1]
    /// extrapolates. Position is interpolated on a straight line, heading the shortest way
    /// round; the heading continues from `self.theta_rad` and is not re-wrapped, so a
    /// continuous (unwrapped) heading stays continuous: wrap it where a canonical angle is
    /// needed.
    pub fn lerp(&self, other: &Pose2, w: f64) -> Pose2 {
        Pose2::new(
            self.x_m + w * (other.x_m - self.x_m),
            self.y_m + w * (other.y_m - self.y_m),
            self.theta_rad + w * wrap_angle(other.theta_rad - self.theta_rad),
        )
    }

    /// This pose expressed relative to `origin` (i.e. origin⁻¹ · self).
    pub fn relative_to(&self, origin: &Pose2) -> Pose2 {
        origin.inverse().compose(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn wrap_stays_in_range() {
        for k in -20..20 {
            let a = k as f64 * 0.7;
            let w = wrap_angle(a);
            assert!(w > -PI - 1e-12 && w <= PI + 1e-12);
            assert!(
                ((a - w) / (2.0 * PI)).fract().abs() < 1e-9
                    || ((a - w) / (2.0 * PI)).fract().abs() > 1.0 - 1e-9
            );
        }
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
    }

    #[test]
    fn lerp_takes_the_short_way_across_pi() {
        let a = Pose2::new(0.0, 1.0, PI - 0.1);
        let b = Pose2::new(2.0, -1.0, -PI + 0.1);
        let m = a.lerp(&b, 0.5);
        assert!((m.x_m - 1.0).abs() < 1e-12 && m.y_m.abs() < 1e-12);
        // Halfway between 179.4 deg and -179.4 deg is 180 deg, not 0.
        assert!((m.theta_rad - PI).abs() < 1e-12, "{}", m.theta_rad);
        let q = a.lerp(&b, 0.75);
        assert!((wrap_angle(q.theta_rad) - (-PI + 0.05)).abs() < 1e-12);
        // And the other way round.
        let m = b.lerp(&a, 0.5);
        assert!((wrap_angle(m.theta_rad).abs() - PI).abs() < 1e-12);
        // Extrapolation continues the motion.
        let e = Pose2::new(0.0, 0.0, 0.0).lerp(&Pose2::new(1.0, 0.0, 0.2), 2.0);
        assert!((e.x_m - 2.0).abs() < 1e-12 && (e.theta_rad - 0.4).abs() < 1e-12);
    }

    #[test]
    fn relative_and_compose_are_inverse() {
        let a = Pose2::new(1.0, -2.0, 0.3);
        let b = Pose2::new(0.5, 0.25, -1.2);
        let r = b.relative_to(&a);
        let back = a.compose(&r);
        assert!((back.x_m - b.x_m).abs() < 1e-12);
        assert!((back.y_m - b.y_m).abs() < 1e-12);
        assert!(wrap_angle(back.theta_rad - b.theta_rad).abs() < 1e-12);
    }
}
