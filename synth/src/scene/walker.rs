//! A person walking through the view between the ceiling camera and the robot, hiding the tag
//! for about [`CameraEffects::occlusion_s`].
//!
//! Seen from a ceiling camera 2.2 m up, a person is their shoulders (an ellipse 0.48 m across
//! and 0.26 m deep at 1.45 m) and head (a disc of 0.1 m radius at 1.70 m), large in the image
//! because they are close to the lens. The walk is a straight line at constant speed, across
//! the robot's motion at a seeded moment in the middle of the video, and its speed is chosen so
//! that the shoulders' shadow cast from the lens onto the tag's plane passes over the tag in
//! `occlusion_s`: the shadow is `(H − m) / (H − h)` times larger than the shoulders or head
//! at height h (H the camera's height, m the marker's). A camera lower than 1.9 m sees no
//! person (they would hit it). Which frames are actually hidden is measured on the
//! rendered geometry ([`Walker::hidden_fraction`]), not taken from this plan.

use super::*;

const SHOULDER_HEIGHT_M: f64 = 1.45;
/// Half axes of the shoulders: across the walking direction and along it.
const SHOULDER_HALF_ACROSS_M: f64 = 0.24;
const SHOULDER_HALF_ALONG_M: f64 = 0.13;
const HEAD_HEIGHT_M: f64 = 1.70;
const HEAD_RADIUS_M: f64 = 0.10;
const SHIRT: f32 = 75.0;
const HAIR: f32 = 35.0;

/// Where the person is at one instant: the floor point under the shoulders' centre and the
/// unit walking direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PersonAt {
    pub(crate) centre: Point2<f64>,
    pub(crate) dir: Vector2<f64>,
}

impl PersonAt {
    /// Radiance of the person along the floor-frame ray `o + s d`, or `None` if it misses.
    #[inline]
    pub(crate) fn radiance(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f32> {
        if d.z >= -1e-12 {
            return None;
        }
        // The head is nearer the camera than the shoulders.
        let s = (HEAD_HEIGHT_M - o.z) / d.z;
        if s > 0.0 {
            let (x, y) = (o.x + s * d.x - self.centre.x, o.y + s * d.y - self.centre.y);
            if x * x + y * y <= HEAD_RADIUS_M * HEAD_RADIUS_M {
                return Some(HAIR);
            }
        }
        let s = (SHOULDER_HEIGHT_M - o.z) / d.z;
        if s > 0.0 {
            let (x, y) = (o.x + s * d.x - self.centre.x, o.y + s * d.y - self.centre.y);
            let along = x * self.dir.x + y * self.dir.y;
            let across = -x * self.dir.y + y * self.dir.x;
            let e =
                (along / SHOULDER_HALF_ALONG_M).powi(2) + (across / SHOULDER_HALF_ACROSS_M).powi(2);
            if e <= 1.0 {
                return Some(SHIRT);
            }
        }
        None
    }

    /// Floor-frame points outlining the person (shoulders and head), for the image box.
    fn outline(&self) -> impl Iterator<Item = Point3<f64>> + '_ {
        let n = Vector2::new(-self.dir.y, self.dir.x);
        (0..16).flat_map(move |k| {
            let a = k as f64 * std::f64::consts::TAU / 16.0;
            // Polygon of 16 vertices around the ellipse: scale by 1/cos(π/16) to enclose it.
            let grow = 1.0 / (std::f64::consts::PI / 16.0).cos();
            let sh = self.centre
                + (self.dir * SHOULDER_HALF_ALONG_M * a.cos()
                    + n * SHOULDER_HALF_ACROSS_M * a.sin())
                    * grow;
            let hd = self.centre + Vector2::new(a.cos(), a.sin()) * HEAD_RADIUS_M * grow;
            [
                Point3::new(sh.x, sh.y, SHOULDER_HEIGHT_M),
                Point3::new(hd.x, hd.y, HEAD_HEIGHT_M),
            ]
        })
    }
}

/// The walk of the person through one video.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Walker {
    /// When the shoulders' shadow is centred on the tag, seconds.
    pub(crate) t_mid_s: f64,
    mid: Point2<f64>,
    dir: Vector2<f64>,
    speed_mps: f64,
}

impl Walker {
    /// Plans the walk for a video of `trajectory` (None without an occlusion).
    pub(crate) fn plan(
        config: &SceneConfig,
        trajectory: &[(f64, Pose2)],
        seed: u64,
    ) -> Option<Self> {
        let occlusion_s = config.effects.occlusion_s;
        if occlusion_s <= 0.0 {
            return None;
        }
        let (t0, t1) = (trajectory.first()?.0, trajectory.last()?.0);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x09e2_50a1_4a1c);
        let t_mid_s = t0 + (t1 - t0) * rng.gen_range(0.3..0.7);
        let robot = pose_at(trajectory, t_mid_s)?;
        let dt = 0.01;
        let ahead = pose_at(trajectory, t_mid_s + dt)?;
        let behind = pose_at(trajectory, t_mid_s - dt)?;
        let v = (ahead.position() - behind.position()) / (2.0 * dt);
        let across: f64 = if v.norm() > 1e-3 {
            v.y.atan2(v.x) + std::f64::consts::FRAC_PI_2
        } else {
            rng.gen_range(0.0..std::f64::consts::TAU)
        };
        let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        let dir = Vector2::new(across.cos(), across.sin()) * sign;
        let c = config.floor.0.inverse().translation.vector;
        if c.z < HEAD_HEIGHT_M + 0.2 {
            return None;
        }
        let m = config.robot.marker_height_m;
        // Magnification of the shoulders' and the head's shadows from the lens onto the
        // marker plane; the head, nearer the lens, can cast the longer one.
        let k = (c.z - m) / (c.z - SHOULDER_HEIGHT_M);
        let k_head = (c.z - m) / (c.z - HEAD_HEIGHT_M);
        let plate = config.robot.tag_size_m * 10.0 / 8.0;
        let shadow_along =
            (2.0 * SHOULDER_HALF_ALONG_M * k).max(2.0 * HEAD_RADIUS_M * k_head) + plate;
        let speed_mps = shadow_along / occlusion_s / k;
        // The person stands where their shadow from the lens covers the robot.
        let mid = Point2::new(c.x + (robot.x_m - c.x) / k, c.y + (robot.y_m - c.y) / k);
        Some(Self {
            t_mid_s,
            mid,
            dir,
            speed_mps,
        })
    }

    /// Where the person is at `t_s`.
    pub(crate) fn at(&self, t_s: f64) -> PersonAt {
        PersonAt {
            centre: self.mid + self.dir * self.speed_mps * (t_s - self.t_mid_s),
            dir: self.dir,
        }
    }

    /// Pixel box (x0, y0, x1, y1 exclusive) the person covers at the given times, or `None`
    /// if they are out of the image then.
    pub(crate) fn image_box(
        &self,
        camera: &CameraModel,
        floor: &FloorToCamera,
        times: &[f64],
    ) -> Option<(u32, u32, u32, u32)> {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for &t in times {
            for q in self.at(t).outline() {
                let px = camera.project(&(floor.0 * q))?;
                x0 = x0.min(px.x);
                y0 = y0.min(px.y);
                x1 = x1.max(px.x);
                y1 = y1.max(px.y);
            }
        }
        let m = 2.0;
        let bx0 = (x0 - m).floor().max(0.0);
        let by0 = (y0 - m).floor().max(0.0);
        let bx1 = (x1 + m).ceil().min(camera.width as f64);
        let by1 = (y1 + m).ceil().min(camera.height as f64);
        if bx1 <= bx0 || by1 <= by0 {
            return None;
        }
        Some((bx0 as u32, by0 as u32, bx1 as u32, by1 as u32))
    }

    /// Fraction of the tag's printed plate (a 12×12 grid of points on it, robot at `pose`)
    /// whose line of sight to the camera the person blocks at `t_s`.
    pub(crate) fn hidden_fraction(
        &self,
        config: &SceneConfig,
        plate_m: f64,
        pose: &Pose2,
        t_s: f64,
    ) -> f64 {
        let person = self.at(t_s);
        let o = config.floor.0.inverse().translation.vector;
        let n = 12;
        let mut hidden = 0;
        for i in 0..n {
            for j in 0..n {
                let local = Point2::new(
                    plate_m * ((i as f64 + 0.5) / n as f64 - 0.5),
                    plate_m * ((j as f64 + 0.5) / n as f64 - 0.5),
                );
                let q = pose.transform_point(&local);
                let d = Vector3::new(q.x - o.x, q.y - o.y, config.robot.marker_height_m - o.z);
                hidden += usize::from(person.radiance(&o, &d).is_some());
            }
        }
        hidden as f64 / (n * n) as f64
    }
}
