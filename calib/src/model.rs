//! The camera model: pinhole intrinsics with one of OpenCV's lens models (the
//! five-coefficient model, the rational model, or Kannala–Brandt fisheye). The
//! renderer and the estimator both use it, so what is rendered is exactly what
//! is estimated; OpenCV's own projection is checked against it in the tests.

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

/// The lens model families odocal fits, each one of OpenCV's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LensModel {
    /// OpenCV's default five coefficients k1 k2 p1 p2 k3 (Brown–Conrady; ROS `plumb_bob`).
    Pinhole5,
    /// OpenCV's rational model (`CALIB_RATIONAL_MODEL`): k1 k2 p1 p2 k3 k4 k5 k6, a ratio of
    /// radial polynomials, for wide lenses up to about 120° (ROS `rational_polynomial`).
    Rational,
    /// Kannala–Brandt equidistant (`cv::fisheye`): k1..k4 on the angle from the axis, for
    /// fisheye lenses up to about 180° (ROS `equidistant`).
    Fisheye,
}

impl LensModel {
    /// Every model, simplest first (fewest coefficients, then OpenCV's default first).
    pub const ALL: [LensModel; 3] = [LensModel::Fisheye, LensModel::Pinhole5, LensModel::Rational];

    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            LensModel::Pinhole5 => "pinhole5",
            LensModel::Rational => "rational",
            LensModel::Fisheye => "fisheye",
        }
    }

    /// Parses a name as [`LensModel::name`] writes it.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == s)
    }

    /// The coefficient names in OpenCV's order for this model.
    pub fn coefficient_names(self) -> &'static [&'static str] {
        match self {
            LensModel::Pinhole5 => &["k1", "k2", "p1", "p2", "k3"],
            LensModel::Rational => &["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"],
            LensModel::Fisheye => &["k1", "k2", "k3", "k4"],
        }
    }

    /// ROS camera_info's name for this model.
    pub fn ros_name(self) -> &'static str {
        match self {
            LensModel::Pinhole5 => "plumb_bob",
            LensModel::Rational => "rational_polynomial",
            LensModel::Fisheye => "equidistant",
        }
    }
}

impl std::fmt::Display for LensModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Lens distortion: the model and its coefficients in OpenCV's order for that model
/// ([`LensModel::coefficient_names`]); unused trailing entries are zero.
///
/// All models map an ideal normalised image point (x/z, y/z) of a point in front of the
/// camera to a distorted normalised point, which the intrinsics take to pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distortion {
    /// Which model the coefficients belong to.
    pub model: LensModel,
    coeffs: [f64; 8],
}

impl Default for Distortion {
    /// No distortion, OpenCV's default model.
    fn default() -> Self {
        Self::zero(LensModel::Pinhole5)
    }
}

impl Distortion {
    /// A model with every coefficient zero (the ideal lens of that model).
    pub fn zero(model: LensModel) -> Self {
        Self {
            model,
            coeffs: [0.0; 8],
        }
    }

    /// Builds from coefficients in OpenCV's order for `model`; extra values must be zero
    /// (OpenCV returns 14 for the rational model with the thin-prism and tilt terms unused).
    pub fn new(model: LensModel, coeffs: &[f64]) -> Self {
        let mut c = [0.0; 8];
        let n = model.coefficient_names().len();
        for (dst, src) in c.iter_mut().zip(coeffs.iter().take(n)) {
            *dst = *src;
        }
        Self { model, coeffs: c }
    }

    /// OpenCV's five-coefficient model from k1 k2 p1 p2 k3.
    pub fn pinhole5(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Self {
        Self::new(LensModel::Pinhole5, &[k1, k2, p1, p2, k3])
    }

    /// The coefficients in OpenCV's order for the model (5, 8 or 4 values).
    pub fn to_opencv(&self) -> Vec<f64> {
        self.coefficients().to_vec()
    }

    /// The coefficients in OpenCV's order for the model.
    pub fn coefficients(&self) -> &[f64] {
        &self.coeffs[..self.model.coefficient_names().len()]
    }

    /// Mutable access to the coefficients (for perturbing one in a numerical derivative).
    pub fn coefficients_mut(&mut self) -> &mut [f64] {
        let n = self.model.coefficient_names().len();
        &mut self.coeffs[..n]
    }

    /// One coefficient by name (`"k1"`, `"p2"`, ...); `None` if the model has no such term.
    pub fn get(&self, name: &str) -> Option<f64> {
        let i = self
            .model
            .coefficient_names()
            .iter()
            .position(|n| *n == name)?;
        Some(self.coeffs[i])
    }

    /// Distorts an ideal normalised image point (x/z, y/z).
    pub fn distort(&self, u: Vector2<f64>) -> Vector2<f64> {
        let c = &self.coeffs;
        let (x, y) = (u.x, u.y);
        let r2 = x * x + y * y;
        match self.model {
            LensModel::Fisheye => {
                let r = r2.sqrt();
                if r < 1e-15 {
                    return u;
                }
                let th = r.atan();
                let t2 = th * th;
                let thd = th * (1.0 + t2 * (c[0] + t2 * (c[1] + t2 * (c[2] + t2 * c[3]))));
                u * (thd / r)
            }
            LensModel::Pinhole5 | LensModel::Rational => {
                let (k1, k2, p1, p2, k3) = (c[0], c[1], c[2], c[3], c[4]);
                let mut radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
                if self.model == LensModel::Rational {
                    radial /= 1.0 + r2 * (c[5] + r2 * (c[6] + r2 * c[7]));
                }
                Vector2::new(
                    x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                    y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
                )
            }
        }
    }

    /// Inverts [`Distortion::distort`]: the fisheye model by Newton's method on the angle
    /// from the axis; the others by fixed-point iteration (as OpenCV's undistortPoints)
    /// refined with Newton steps for sub-1e-12 accuracy.
    pub fn undistort(&self, d: Vector2<f64>) -> Vector2<f64> {
        if self.model == LensModel::Fisheye {
            return self.undistort_fisheye(d);
        }
        let c = &self.coeffs;
        let mut u = d;
        for _ in 0..20 {
            let (x, y) = (u.x, u.y);
            let r2 = x * x + y * y;
            let mut radial = 1.0 + r2 * (c[0] + r2 * (c[1] + r2 * c[4]));
            if self.model == LensModel::Rational {
                radial /= 1.0 + r2 * (c[5] + r2 * (c[6] + r2 * c[7]));
            }
            if !(radial.is_finite() && radial > 1e-6) {
                break;
            }
            let dx = 2.0 * c[2] * x * y + c[3] * (r2 + 2.0 * x * x);
            let dy = c[2] * (r2 + 2.0 * y * y) + 2.0 * c[3] * x * y;
            let next = Vector2::new((d.x - dx) / radial, (d.y - dy) / radial);
            // Close enough for the Newton steps below, which converge quadratically from
            // here to the last digits. Stopping early is
            // what makes rendering a wide lens's ray grid (millions of pixels) cheap.
            let settled = (next - u).norm() < 1e-9 * (1.0 + u.norm());
            u = next;
            if settled {
                break;
            }
        }
        for _ in 0..8 {
            let at_u = self.distort(u);
            let e = at_u - d;
            if e.norm() < 1e-15 * (1.0 + d.norm()) {
                break;
            }
            let h = 1e-7 * (1.0 + u.norm());
            let jx = (self.distort(u + Vector2::new(h, 0.0)) - at_u) / h;
            let jy = (self.distort(u + Vector2::new(0.0, h)) - at_u) / h;
            let j = nalgebra::Matrix2::from_columns(&[jx, jy]);
            match j.try_inverse() {
                Some(ji) => u -= ji * e,
                None => break,
            }
        }
        u
    }

    fn undistort_fisheye(&self, d: Vector2<f64>) -> Vector2<f64> {
        let c = &self.coeffs;
        let thd = d.norm();
        if thd < 1e-15 {
            return d;
        }
        // θd = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸), solved for θ in [0, π/2).
        let mut th = thd.min(1.5);
        for _ in 0..30 {
            let t2 = th * th;
            let f = th * (1.0 + t2 * (c[0] + t2 * (c[1] + t2 * (c[2] + t2 * c[3])))) - thd;
            let df =
                1.0 + t2 * (3.0 * c[0] + t2 * (5.0 * c[1] + t2 * (7.0 * c[2] + t2 * 9.0 * c[3])));
            if df.abs() < 1e-12 {
                break;
            }
            let step = f / df;
            th = (th - step).clamp(0.0, std::f64::consts::FRAC_PI_2 - 1e-6);
            if step.abs() < 1e-15 {
                break;
            }
        }
        d * (th.tan() / thd)
    }
}

/// camera.json's distortion: `{"model": "rational", "k1": .., "k2": .., ...}`; files written
/// before lens models existed have no `model` and are OpenCV's five-coefficient model.
#[derive(Serialize, Deserialize)]
struct DistortionJson {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    model: Option<LensModel>,
    #[serde(flatten)]
    coeffs: std::collections::BTreeMap<String, f64>,
}

impl Serialize for Distortion {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        DistortionJson {
            model: Some(self.model),
            coeffs: self
                .model
                .coefficient_names()
                .iter()
                .zip(self.coefficients())
                .map(|(n, v)| (n.to_string(), *v))
                .collect(),
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for Distortion {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let j = DistortionJson::deserialize(d)?;
        let model = j.model.unwrap_or(LensModel::Pinhole5);
        let names = model.coefficient_names();
        if let Some(extra) = j.coeffs.keys().find(|k| !names.contains(&k.as_str())) {
            return Err(D::Error::custom(format!(
                "distortion has a coefficient {extra:?} that the {model} model does not have (it has {})",
                names.join(" ")
            )));
        }
        let mut c = Vec::with_capacity(names.len());
        for n in names {
            match j.coeffs.get(*n) {
                Some(v) => c.push(*v),
                None => {
                    return Err(D::Error::custom(format!(
                        "distortion of the {model} model lacks {n} (it needs {})",
                        names.join(" ")
                    )))
                }
            }
        }
        Ok(Distortion::new(model, &c))
    }
}

/// A camera: image size, intrinsics and distortion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraModel {
    /// Image width, pixels.
    #[serde(deserialize_with = "whole_width")]
    pub width: u32,
    /// Image height, pixels.
    #[serde(deserialize_with = "whole_height")]
    pub height: u32,
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Lens distortion.
    pub distortion: Distortion,
}

/// An image size in pixels: tools that write every number with a point (`1280.0`) are read
/// when the number is whole.
fn whole_pixels<'de, D: serde::Deserializer<'de>>(d: D, field: &str) -> Result<u32, D::Error> {
    let v = f64::deserialize(d)?;
    if v.fract() == 0.0 && (0.0..=f64::from(u32::MAX)).contains(&v) {
        Ok(v as u32)
    } else {
        Err(serde::de::Error::custom(format!(
            "{field} must be a whole number of pixels, not {v}"
        )))
    }
}

fn whole_width<'de, D: serde::Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    whole_pixels(d, "width")
}

fn whole_height<'de, D: serde::Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    whole_pixels(d, "height")
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
        Self::with_lens(width, height, hfov_deg, Distortion::default())
    }

    /// A camera with the given lens whose focal length makes the image's left and right
    /// edges (through the principal point at the image centre) `hfov_deg` apart.
    pub fn with_lens(width: u32, height: u32, hfov_deg: f64, distortion: Distortion) -> Self {
        let edge = distortion.distort(Vector2::new((hfov_deg.to_radians() / 2.0).tan(), 0.0));
        let f = (width as f64 / 2.0) / edge.x;
        Self {
            width,
            height,
            intrinsics: Intrinsics {
                fx: f,
                fy: f,
                cx: (width as f64 - 1.0) / 2.0,
                cy: (height as f64 - 1.0) / 2.0,
            },
            distortion,
        }
    }

    /// The intrinsic parameters as one vector: fx fy cx cy and the distortion coefficients
    /// in OpenCV's order (the order of camera.json's covariance).
    pub fn parameters(&self) -> Vec<f64> {
        let k = &self.intrinsics;
        let mut p = vec![k.fx, k.fy, k.cx, k.cy];
        p.extend_from_slice(self.distortion.coefficients());
        p
    }

    /// The names of [`CameraModel::parameters`], in order.
    pub fn parameter_names(&self) -> Vec<&'static str> {
        let mut n = vec!["fx", "fy", "cx", "cy"];
        n.extend_from_slice(self.distortion.model.coefficient_names());
        n
    }

    /// The same camera with the parameters of [`CameraModel::parameters`] replaced.
    pub fn with_parameters(&self, p: &[f64]) -> Self {
        let mut c = *self;
        if p.len() >= 4 {
            c.intrinsics = Intrinsics {
                fx: p[0],
                fy: p[1],
                cx: p[2],
                cy: p[3],
            };
            for (dst, src) in c.distortion.coefficients_mut().iter_mut().zip(&p[4..]) {
                *dst = *src;
            }
        }
        c
    }

    /// Projects a point in the camera frame to a pixel; `None` behind the camera.
    pub fn project(&self, p_cam: &Point3<f64>) -> Option<Point2<f64>> {
        if p_cam.z <= 1e-9 || !p_cam.z.is_finite() {
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
        c.distortion = Distortion::pinhole5(-0.12, 0.05, 4e-4, -3e-4, -0.01);
        c
    }

    /// Over the whole image, corners included, of a 70° five-coefficient lens, a 110°
    /// rational lens with strong barrel distortion and a 150° fisheye (the renderer's lenses):
    /// the inverse stops iterating early, so this is what bounds its accuracy.
    #[test]
    fn unproject_inverts_project_over_the_image() {
        let rational = Distortion::new(
            LensModel::Rational,
            &[0.5, 0.1, 1.0e-3, -8e-4, 0.0, 0.85, 0.25, 0.01],
        );
        let fisheye = Distortion::new(LensModel::Fisheye, &[-0.013, 0.004, -0.0012, 0.0001]);
        for c in [
            camera(),
            CameraModel::with_lens(1280, 720, 110.0, rational),
            CameraModel::with_lens(1280, 720, 150.0, fisheye),
        ] {
            for py in (0..=720).step_by(45) {
                for px in (0..=1280).step_by(64) {
                    let pix = Point2::new(px as f64 - 0.5, py as f64 - 0.5);
                    let u = c.unproject(&pix);
                    let back = c.project(&Point3::new(u.x, u.y, 1.0)).unwrap();
                    assert!(
                        (back - pix).norm() < 1e-9,
                        "{:?}: {pix} -> {back}",
                        c.distortion.model
                    );
                }
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
