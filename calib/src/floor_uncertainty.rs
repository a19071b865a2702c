//! How far off the floor point seen at each pixel may be: the calibration's uncertainty
//! carried all the way to floor coordinates, in millimetres.
//!
//! The camera-frame map of [`crate::UncertaintyMap`] overstates what a user of the floor
//! mapping sees: the floor plane is located with the same intrinsics, so an error in, say,
//! the principal point mostly moves the floor frame with it (mrcal's point that projection
//! uncertainty must be judged in the frame the user measures in). Here a change of the
//! intrinsics moves both the pixel's ray and the floor boards (located again with the new
//! intrinsics, so the floor plane moves too), and the floor boards' own corner noise adds
//! each board pose's covariance through the same plane fit. The result is
//! one standard deviation along the worst floor direction, per cell of a grid over the image.

use nalgebra::{DMatrix, Isometry3, Matrix2, Matrix6, Point2, UnitQuaternion, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use crate::floor::{board_pose, plane_from_poses};
use crate::uncertainty::{residuals, steps, view_jacobians, worst_sigma};
use crate::{
    BoardSpec, BoardToCamera, BoardView, CalibError, CameraModel, FloorToCamera, Observation,
    UncertaintyMap,
};

/// Rays more than this far from straight down graze the floor; such cells are not mapped
/// (walls, or the floor so far off that one pixel spans decimetres).
pub const FLOOR_SEEN_MAX_OFF_NADIR_DEG: f64 = 80.0;

/// The floor-mapping bound whose reach `odocal calibrate` reports, millimetres ...
pub const FLOOR_BOUND_MM: f64 = 2.0;
/// ... held at this many standard deviations of [`FloorUncertaintyMap`]'s σ.
pub const FLOOR_BOUND_SIGMAS: f64 = 3.0;

/// The floor around the point under the camera that a calibration maps within a given
/// uncertainty ([`FloorUncertaintyMap::reach`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorReach {
    /// Radius of the disc, metres on the floor from the point under the camera.
    pub radius_m: f64,
    /// The same as an angle off the nadir, degrees.
    pub off_nadir_deg: f64,
    /// Whether the disc holds every mapped cell (no cell exceeds the uncertainty).
    pub whole: bool,
    /// The largest σ over the mapped floor, millimetres.
    pub worst_sigma_mm: f64,
}

impl FloorReach {
    /// One line for people: how far out the floor is vouched for, at [`FLOOR_BOUND_MM`] and
    /// [`FLOOR_BOUND_SIGMAS`] (the bound [`FloorUncertaintyMap::vouched_reach`] uses), and
    /// what extends it.
    pub fn sentence(&self) -> String {
        let bound = format!("within {FLOOR_BOUND_MM} mm ({FLOOR_BOUND_SIGMAS}σ)");
        if self.whole {
            format!(
                "the whole floor the image sees is mapped {bound}: out to {:.2} m from the point under the camera ({:.0}° off the nadir)",
                self.radius_m, self.off_nadir_deg
            )
        } else {
            format!(
                "floor mapped {bound} out to {:.2} m from the point under the camera ({:.0}° off the nadir); farther out 1σ grows to {:.1} mm: add floor views farther out and hand-held views reaching the image's edges",
                self.radius_m, self.off_nadir_deg, self.worst_sigma_mm
            )
        }
    }
}

/// Floor-position uncertainty over the image on a grid of cells.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FloorUncertaintyMap {
    /// Side of a cell, pixels.
    pub cell_px: u32,
    /// Cells across.
    pub cols: u32,
    /// Cells down.
    pub rows: u32,
    /// One standard deviation of the floor point seen at each cell centre, along its worst
    /// floor direction, millimetres, row by row; `None` where the cell does not see the floor
    /// (its ray is more than [`FLOOR_SEEN_MAX_OFF_NADIR_DEG`] from straight down).
    pub sigma_mm: Vec<Option<f64>>,
    /// Each floor board's detected corners, pixels: where the floor plane was measured.
    pub floor_boards_px: Vec<Vec<[f64; 2]>>,
}

impl FloorUncertaintyMap {
    /// The map for `camera`, whose intrinsics have `covariance`, with the floor located from
    /// `floor_views` of `board`; `corner_sigma_px` is the corners' noise per coordinate.
    pub fn new(
        camera: &CameraModel,
        covariance: &DMatrix<f64>,
        floor_views: &[BoardView],
        board: &BoardSpec,
        corner_sigma_px: f64,
        cell_px: u32,
    ) -> Result<Self, CalibError> {
        let p0 = camera.parameters();
        if covariance.nrows() != p0.len() || covariance.ncols() != p0.len() {
            return Err(CalibError::Input(format!(
                "the covariance is {}x{} but the {} camera has {} parameters",
                covariance.nrows(),
                covariance.ncols(),
                camera.distortion.model,
                p0.len()
            )));
        }
        let poses = floor_views
            .iter()
            .map(|v| board_pose(camera, v, board))
            .collect::<Result<Vec<_>, _>>()?;
        let floor = plane_from_poses(&poses, floor_views)?.floor_to_camera;
        let cell_px = cell_px.max(1);
        let cols = camera.width.div_ceil(cell_px);
        let rows = camera.height.div_ceil(cell_px);
        let pixels: Vec<Point2<f64>> = (0..rows)
            .flat_map(|r| (0..cols).map(move |c| (c, r)))
            .map(|(c, r)| UncertaintyMap::centre(camera, cell_px, c, r))
            .collect();
        let seen: Vec<bool> = pixels
            .iter()
            .map(|p| sees_floor(camera, &floor, p))
            .collect();
        let n = p0.len();
        // d(floor point)/d(intrinsics): the ray moves with the intrinsics directly, and the
        // floor frame moves with the boards, which are located again with the new intrinsics;
        // at the boards' optimum that second move is the Gauss-Newton sensitivity
        // dpose/dθ = -(JpᵀJp)⁻¹ JpᵀJi, so nothing is refitted numerically.
        let mut j_int = vec![DMatrix::<f64>::zeros(2, n); pixels.len()];
        let hs = steps(camera);
        for (i, h) in hs.iter().enumerate() {
            let (mut plus, mut minus) = (p0.clone(), p0.clone());
            plus[i] += h;
            minus[i] -= h;
            let (cp, cm) = (
                camera.with_parameters(&plus),
                camera.with_parameters(&minus),
            );
            for (k, pix) in pixels.iter().enumerate() {
                if let Some(d) = difference(&cp, &floor, &cm, &floor, pix) {
                    j_int[k][(0, i)] = d.x / (2.0 * h);
                    j_int[k][(1, i)] = d.y / (2.0 * h);
                }
            }
        }
        let mut cov = vec![Matrix2::<f64>::zeros(); pixels.len()];
        let h = 1e-6;
        for (b, (view, pose)) in floor_views.iter().zip(&poses).enumerate() {
            let o = Observation {
                pose: *pose,
                object: &view.object_points,
                image: &view.corners,
            };
            let (ji, _) = view_jacobians(camera, &o);
            let jp = pose_jacobian(camera, &o);
            let info = jp.transpose() * &jp;
            let Some(info_inv) = Matrix6::from_iterator(info.iter().copied()).try_inverse() else {
                continue;
            };
            let info_inv = DMatrix::from_iterator(6, 6, info_inv.iter().copied());
            let dpose_dtheta = -(&info_inv * jp.transpose() * &ji);
            let pose_cov = info_inv * board_corner_sigma_px(camera, &o, corner_sigma_px).powi(2);
            // d(floor point)/d(this board's pose), through the plane fit.
            let mut jb = vec![DMatrix::<f64>::zeros(2, 6); pixels.len()];
            for d in 0..6 {
                let plane = |sign: f64| -> Result<FloorToCamera, CalibError> {
                    let mut moved = poses.clone();
                    moved[b] = BoardToCamera(board_nudge(&pose.0, d, sign * h));
                    Ok(plane_from_poses(&moved, floor_views)?.floor_to_camera)
                };
                let (fp, fm) = (plane(1.0)?, plane(-1.0)?);
                for (k, pix) in pixels.iter().enumerate() {
                    if let Some(dd) = difference(camera, &fp, camera, &fm, pix) {
                        jb[k][(0, d)] = dd.x / (2.0 * h);
                        jb[k][(1, d)] = dd.y / (2.0 * h);
                    }
                }
            }
            for k in 0..pixels.len() {
                j_int[k] += &jb[k] * &dpose_dtheta;
                let s = &jb[k] * &pose_cov * jb[k].transpose();
                cov[k] += Matrix2::new(s[(0, 0)], s[(0, 1)], s[(1, 0)], s[(1, 1)]);
            }
        }
        for (c, j) in cov.iter_mut().zip(&j_int) {
            let s = j * covariance * j.transpose();
            *c += Matrix2::new(s[(0, 0)], s[(0, 1)], s[(1, 0)], s[(1, 1)]);
        }

        let sigma_mm = cov
            .iter()
            .zip(&seen)
            .map(|(c, &s)| {
                let worst = worst_sigma(c);
                (s && worst.is_finite()).then_some(worst * 1000.0)
            })
            .collect();
        Ok(Self {
            cell_px,
            cols,
            rows,
            sigma_mm,
            floor_boards_px: floor_views
                .iter()
                .map(|v| v.corners.iter().map(|p| [p.x, p.y]).collect())
                .collect(),
        })
    }

    /// The σ of the cell holding `pixel`, millimetres (None off the map or off the floor).
    pub fn at(&self, pixel: &Point2<f64>) -> Option<f64> {
        if pixel.x < 0.0 || pixel.y < 0.0 {
            return None;
        }
        let c = (pixel.x / self.cell_px as f64) as u32;
        let r = (pixel.y / self.cell_px as f64) as u32;
        if c >= self.cols || r >= self.rows {
            return None;
        }
        self.sigma_mm
            .get((r * self.cols + c) as usize)
            .copied()
            .flatten()
    }

    /// How far out from the point under the camera the floor is mapped with at most
    /// `sigma_mm` of uncertainty (1σ): the disc around that point in which every mapped cell
    /// stays within it, up to the nearest cell that does not (or, when none exceeds it, out
    /// to the farthest mapped cell). `camera` and `floor` are the calibration's own.
    pub fn reach(
        &self,
        camera: &CameraModel,
        floor: &FloorToCamera,
        sigma_mm: f64,
    ) -> Option<FloorReach> {
        let above = floor.0.inverse().translation.vector;
        let under = Point2::new(above.x, above.y);
        let (mut nearest_over, mut farthest) = (f64::INFINITY, 0.0f64);
        let mut worst_mm: f64 = 0.0;
        for r in 0..self.rows {
            for c in 0..self.cols {
                let Some(Some(s)) = self.sigma_mm.get((r * self.cols + c) as usize) else {
                    continue;
                };
                let pix = UncertaintyMap::centre(camera, self.cell_px, c, r);
                let Some(p) = camera.pixel_to_floor(floor, &pix, 0.0) else {
                    continue;
                };
                let d = (p - under).norm();
                farthest = farthest.max(d);
                worst_mm = worst_mm.max(*s);
                if *s > sigma_mm {
                    nearest_over = nearest_over.min(d);
                }
            }
        }
        if farthest == 0.0 {
            return None;
        }
        let whole = nearest_over.is_infinite();
        let radius_m = if whole { farthest } else { nearest_over };
        Some(FloorReach {
            radius_m,
            off_nadir_deg: radius_m.atan2(above.z.abs()).to_degrees(),
            whole,
            worst_sigma_mm: worst_mm,
        })
    }

    /// [`Self::reach`] at the bound odocal vouches for: [`FLOOR_BOUND_MM`] at
    /// [`FLOOR_BOUND_SIGMAS`].
    pub fn vouched_reach(&self, camera: &CameraModel, floor: &FloorToCamera) -> Option<FloorReach> {
        self.reach(camera, floor, FLOOR_BOUND_MM / FLOOR_BOUND_SIGMAS)
    }

    /// The median and the largest σ over the cells that see the floor, millimetres.
    pub fn median_and_max_mm(&self) -> Option<(f64, f64)> {
        let mut v: Vec<f64> = self.sigma_mm.iter().flatten().copied().collect();
        v.sort_by(f64::total_cmp);
        Some((*v.get(v.len() / 2)?, *v.last()?))
    }
}

/// A floor board's corner noise per coordinate, pixels: the calibration's `corner_sigma_px`,
/// unless the board's own fit residuals are larger beyond chance (their variance above the
/// 99.9 % point of its spread over the board's degrees of freedom), which they are when,
/// say, the board's edges run along the pixel grid and its sub-pixel corners are pulled
/// towards it: several times the views' noise, on the board that fixes the floor's origin.
fn board_corner_sigma_px(camera: &CameraModel, o: &Observation, corner_sigma_px: f64) -> f64 {
    let own: Vec<f64> = residuals(camera, &o.pose.0, o)
        .into_iter()
        .filter(|v| v.is_finite())
        .collect();
    let dof = own.len().saturating_sub(6).max(1) as f64;
    let own_var = own.iter().map(|v| v * v).sum::<f64>() / dof;
    let beyond_chance = 1.0 + 3.1 * (2.0 / dof).sqrt();
    if own_var > beyond_chance * corner_sigma_px.powi(2) {
        own_var.sqrt()
    } else {
        corner_sigma_px
    }
}

/// Whether the ray through `pixel` meets the floor within [`FLOOR_SEEN_MAX_OFF_NADIR_DEG`]
/// of straight down.
fn sees_floor(camera: &CameraModel, floor: &FloorToCamera, pixel: &Point2<f64>) -> bool {
    let down = floor.0.rotation * -nalgebra::Vector3::z();
    let cos = camera.ray(pixel).dot(&down);
    cos > FLOOR_SEEN_MAX_OFF_NADIR_DEG.to_radians().cos()
}

/// The floor point seen at `pixel` by the first camera and floor minus that of the second.
fn difference(
    cam_a: &CameraModel,
    floor_a: &FloorToCamera,
    cam_b: &CameraModel,
    floor_b: &FloorToCamera,
    pixel: &Point2<f64>,
) -> Option<Vector2<f64>> {
    let a = cam_a.pixel_to_floor(floor_a, pixel, 0.0)?;
    let b = cam_b.pixel_to_floor(floor_b, pixel, 0.0)?;
    Some(a - b)
}

/// A board pose turned by `h` radians about camera-frame axis `k` around the board's own
/// origin (k < 3), or moved `h` metres along axis `k - 3`. Turning about the board rather than
/// the camera keeps rotation and translation nearly independent for a board metres away,
/// which keeps the pose's information matrix well conditioned.
fn board_nudge(pose: &Isometry3<f64>, k: usize, h: f64) -> Isometry3<f64> {
    let mut p = *pose;
    if k < 3 {
        let mut w = Vector3::zeros();
        w[k] = h;
        p.rotation = UnitQuaternion::from_scaled_axis(w) * p.rotation;
    } else {
        p.translation.vector[k - 3] += h;
    }
    p
}

/// Derivatives of a view's pixel residuals with respect to its pose, as [`board_nudge`]
/// moves it.
fn pose_jacobian(camera: &CameraModel, o: &Observation) -> DMatrix<f64> {
    let n = 2 * o.object.len();
    let mut jp = DMatrix::zeros(n, 6);
    let h = 1e-7;
    for k in 0..6 {
        let rp = residuals(camera, &board_nudge(&o.pose.0, k, h), o);
        let rm = residuals(camera, &board_nudge(&o.pose.0, k, -h), o);
        for r in 0..n {
            jp[(r, k)] = (rp[r] - rm[r]) / (2.0 * h);
        }
    }
    jp
}
