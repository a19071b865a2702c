//! The camera model: pinhole intrinsics with OpenCV's five-parameter
//! distortion (k1 k2 p1 p2 k3). The renderer and the estimator both use it,
//! so what is rendered is exactly what is estimated.

use nalgebra::{Isometry3, Matrix3, Point2, Point3, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Pinhole intrinsics in pixels (OpenCV convention: pixel centres at integers).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

impl Intrinsics {
    /// The 3x3 camera matrix K.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }
}

/// Lens distortion in OpenCV's order: radial k1 k2 k3, tangential p1 p2.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    /// Radial coefficient of r².
    pub k1: f64,
    /// Radial coefficient of r⁴.
    pub k2: f64,
    /// First tangential coefficient.
    pub p1: f64,
    /// Second tangential coefficient.
    pub p2: f64,
    /// Radial coefficient of r⁶.
    pub k3: f64,
}

impl Distortion {
    /// The coefficients as OpenCV orders them: k1 k2 p1 p2 k3.
    pub fn to_opencv(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// Builds from OpenCV's order k1 k2 p1 p2 k3.
    pub fn from_opencv(c: [f64; 5]) -> Self {
        Self {
            k1: c[0],
            k2: c[1],
            p1: c[2],
            p2: c[3],
            k3: c[4],
        }
    }

    /// Distorts an ideal normalised image point (x/z, y/z).
    pub fn distort(&self, u: Vector2<f64>) -> Vector2<f64> {
        let (x, y) = (u.x, u.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        Vector2::new(
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Inverts [`Distortion::distort`] by fixed-point iteration (as OpenCV's
    /// undistortPoints does), refined with Newton steps for sub-1e-12 accuracy.
    pub fn undistort(&self, d: Vector2<f64>) -> Vector2<f64> {
        let mut u = d;
        for _ in 0..20 {
            let (x, y) = (u.x, u.y);
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            u = Vector2::new((d.x - dx) / radial, (d.y - dy) / radial);
        }
        for _ in 0..3 {
            let e = self.distort(u) - d;
            if e.norm() < 1e-15 {
                break;
            }
            let h = 1e-7;
            let jx = (self.distort(u + Vector2::new(h, 0.0)) - self.distort(u)) / h;
            let jy = (self.distort(u + Vector2::new(0.0, h)) - self.distort(u)) / h;
            let j = nalgebra::Matrix2::from_columns(&[jx, jy]);
            match j.try_inverse() {
                Some(ji) => u -= ji * e,
                None => break,
            }
        }
        u
    }
}

/// A camera: image size, intrinsics and distortion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraModel {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Lens distortion.
    pub distortion: Distortion,
}

/// A rigid transform mapping points in the floor frame (z up, metres) into the
/// camera frame (OpenCV: x right, y down, z along the optical axis).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FloorToCamera(pub Isometry3<f64>);

/// A rigid transform mapping points in a checkerboard's frame (origin at the
/// first inner corner, x along a row, y down the columns, z into the board) into
/// the camera frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoardToCamera(pub Isometry3<f64>);

impl CameraModel {
    /// A distortion-free camera of the given size and horizontal field of view,
    /// principal point at the image centre.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f64) -> Self {
        let f = (width as f64 / 2.0) / (hfov_deg.to_radians() / 2.0).tan();
        Self {
            width,
            height,
            intrinsics: Intrinsics {
                fx: f,
                fy: f,
                cx: (width as f64 - 1.0) / 2.0,
                cy: (height as f64 - 1.0) / 2.0,
            },
            distortion: Distortion::default(),
        }
    }

    /// Projects a point in the camera frame to a pixel; `None` behind the camera.
    pub fn project(&self, p_cam: &Point3<f64>) -> Option<Point2<f64>> {
        if p_cam.z <= 1e-9 {
            return None;
        }
        let d = self
            .distortion
            .distort(Vector2::new(p_cam.x / p_cam.z, p_cam.y / p_cam.z));
        let k = &self.intrinsics;
        Some(Point2::new(k.fx * d.x + k.cx, k.fy * d.y + k.cy))
    }

    /// The ideal (undistorted) normalised coordinates of a pixel: the ray
    /// through the pixel is (x, y, 1) in the camera frame.
    pub fn unproject(&self, pixel: &Point2<f64>) -> Vector2<f64> {
        let k = &self.intrinsics;
        self.distortion.undistort(Vector2::new(
            (pixel.x - k.cx) / k.fx,
            (pixel.y - k.cy) / k.fy,
        ))
    }

    /// The unit ray through a pixel, in the camera frame.
    pub fn ray(&self, pixel: &Point2<f64>) -> Vector3<f64> {
        let u = self.unproject(pixel);
        Vector3::new(u.x, u.y, 1.0).normalize()
    }

    /// Intersects the ray through `pixel` with the horizontal plane at
    /// `height_m` above the floor; returns the floor-frame point (x, y) in metres.
    pub fn pixel_to_floor(
        &self,
        floor: &FloorToCamera,
        pixel: &Point2<f64>,
        height_m: f64,
    ) -> Option<Point2<f64>> {
        let u = self.unproject(pixel);
        intersect_plane_z(floor, Vector3::new(u.x, u.y, 1.0), height_m)
    }

    /// Projects the floor-frame point (x, y, `height_m`) to a pixel.
    pub fn floor_to_pixel(
        &self,
        floor: &FloorToCamera,
        p_floor: &Point2<f64>,
        height_m: f64,
    ) -> Option<Point2<f64>> {
        self.project(&(floor.0 * Point3::new(p_floor.x, p_floor.y, height_m)))
    }
}

/// Intersects a camera-frame ray direction with the floor-frame plane
/// z = `height_m`; returns the floor (x, y), or `None` if the plane is behind
/// the camera or parallel to the ray.
pub fn intersect_plane_z(
    floor: &FloorToCamera,
    dir_cam: Vector3<f64>,
    height_m: f64,
) -> Option<Point2<f64>> {
    let camera_to_floor = floor.0.inverse();
    let origin = camera_to_floor.translation.vector;
    let dir = camera_to_floor.rotation * dir_cam;
    if dir.z.abs() < 1e-12 {
        return None;
    }
    let s = (height_m - origin.z) / dir.z;
    if s <= 0.0 {
        return None;
    }
    let p = origin + dir * s;
    Some(Point2::new(p.x, p.y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn camera() -> CameraModel {
        let mut c = CameraModel::from_hfov(1280, 720, 70.0);
        c.distortion = Distortion {
            k1: -0.12,
            k2: 0.05,
            p1: 4e-4,
            p2: -3e-4,
            k3: -0.01,
        };
        c
    }

    #[test]
    fn unproject_inverts_project_over_the_image() {
        let c = camera();
        for py in (0..720).step_by(45) {
            for px in (0..1280).step_by(64) {
                let pix = Point2::new(px as f64, py as f64);
                let u = c.unproject(&pix);
                let back = c.project(&Point3::new(u.x, u.y, 1.0)).unwrap();
                assert!((back - pix).norm() < 1e-9, "{pix} -> {back}");
            }
        }
    }

    #[test]
    fn floor_round_trip() {
        let c = camera();
        // Camera 2.2 m above the floor looking straight down.
        let rot = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let floor = FloorToCamera(Isometry3::from_parts(Translation3::new(0.0, 0.0, 2.2), rot));
        let p = Point2::new(0.7, -0.4);
        let pix = c.floor_to_pixel(&floor, &p, 0.08).unwrap();
        let back = c.pixel_to_floor(&floor, &pix, 0.08).unwrap();
        assert!((back - p).norm() < 1e-9);
    }
}
