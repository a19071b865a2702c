//! Where a ray meets a segment: the one intersection that the laser simulator (drawing
//! scans) and the estimator (walls that hide landmarks) share, so they cannot disagree.

use nalgebra::{Point2, Vector2};

/// Where the ray `origin + t·dir` meets the line through the segment `a + u·(b − a)`:
/// `(t, u)` in units of `dir` and of the segment's length, or None when they are parallel.
/// The segment is hit where `0 ≤ u ≤ 1`, ahead of the origin where `t > 0`; callers choose
/// their own margins.
pub fn ray_segment(
    origin: &Point2<f64>,
    dir: &Vector2<f64>,
    a: &Point2<f64>,
    b: &Point2<f64>,
) -> Option<(f64, f64)> {
    let e = b - a;
    let den = dir.x * e.y - dir.y * e.x;
    if den.abs() < 1e-12 {
        return None;
    }
    let q = a - origin;
    let t = (q.x * e.y - q.y * e.x) / den;
    let u = (q.x * dir.y - q.y * dir.x) / den;
    Some((t, u))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_misses_and_parallels() {
        let o = Point2::new(0.0, 0.0);
        let (a, b) = (Point2::new(2.0, -1.0), Point2::new(2.0, 3.0));
        // Along x, the wall at x = 2 is 2 ahead, a quarter of the way up the segment.
        let (t, u) = ray_segment(&o, &Vector2::new(1.0, 0.0), &a, &b).unwrap();
        assert!((t - 2.0).abs() < 1e-12 && (u - 0.25).abs() < 1e-12);
        // Backwards: behind the origin.
        let (t, _) = ray_segment(&o, &Vector2::new(-1.0, 0.0), &a, &b).unwrap();
        assert!(t < 0.0);
        // Steeply up: past the segment's end.
        let (_, u) = ray_segment(&o, &Vector2::new(0.5, 2.0), &a, &b).unwrap();
        assert!(u > 1.0);
        assert!(ray_segment(&o, &Vector2::new(0.0, 1.0), &a, &b).is_none());
    }
}
