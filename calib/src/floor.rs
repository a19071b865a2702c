//! The floor plane: boards lying flat on the floor, located together on one plane. Each board
//! is first located by solvePnP and a plane fitted through all their corners; that start is
//! then refined by least squares on the corners' reprojection, with every board held on the
//! one plane (the floor's pose, and each board's place and turn on it). Located one by one, a
//! small board's depth and tilt are loose, and those errors tilt the plane; held on the plane,
//! the boards' spread over the floor fixes its tilt, which decides the mapping far from the
//! point under the camera. The first floor view fixes the floor frame's origin (its first
//! inner corner; for a ChArUco board corner 0, whether or not it is in view) and x axis (along
//! its rows); z points up, towards the camera.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use opencv::calib3d;

use crate::opencv_glue::solve_pnp;
use crate::uncertainty::residuals;
use crate::{
    BoardSpec, BoardToCamera, BoardView, CalibError, CameraModel, FloorPlane, FloorToCamera,
    Observation,
};

/// Locates one board in the camera frame with a calibrated camera, from the view's corners
/// and their places on the board (all corners of a checkerboard, those found of a ChArUco
/// board; `board` names it in errors).
pub fn board_pose(
    camera: &CameraModel,
    view: &BoardView,
    board: &BoardSpec,
) -> Result<BoardToCamera, CalibError> {
    if view.object_points.len() != view.corners.len() || view.corners.len() < 4 {
        return Err(CalibError::Input(format!(
            "{}: {} corners of the {} with {} board positions; locating it needs at least 4",
            view.image,
            view.corners.len(),
            crate::charuco::board_name(board),
            view.object_points.len()
        )));
    }
    // A flat board has two poses that fit its corners nearly equally (mirror images about the
    // line of sight); the iterative solver starts from one homography and can settle in the
    // wrong one, or short of the right one, for a small board far off the axis. IPPE solves
    // for both; each start is refined on every corner and the closer fit kept.
    let misfit = |pose: &Isometry3<f64>| {
        let o = Observation {
            pose: BoardToCamera(*pose),
            object: &view.object_points,
            image: &view.corners,
        };
        let r = residuals(camera, pose, &o);
        if r.iter().all(|v| v.is_finite()) {
            r.iter().map(|v| v * v).sum::<f64>()
        } else {
            f64::INFINITY
        }
    };
    let mut best: Option<(f64, Isometry3<f64>)> = None;
    for method in [calib3d::SOLVEPNP_ITERATIVE, calib3d::SOLVEPNP_IPPE] {
        // A method OpenCV cannot apply to these points (IPPE needs them on one plane, as a
        // board's are) is no answer; the other's is kept.
        let Ok(Some(pose)) = solve_pnp(camera, &view.object_points, &view.corners, method) else {
            continue;
        };
        let m = misfit(&pose);
        if best.is_none_or(|(b, _)| m < b) {
            best = Some((m, pose));
        }
    }
    match best {
        Some((_, iso)) => Ok(BoardToCamera(iso)),
        None => Err(CalibError::Input(format!(
            "{}: cannot locate the floor board",
            view.image
        ))),
    }
}

/// Fits the floor plane through the boards of all floor views, each board's corners weighted
/// by their noise ([`board_corner_sigma_px`], from `corner_sigma_px`, the calibration's corner
/// noise per coordinate).
pub fn fit_floor(
    camera: &CameraModel,
    views: &[BoardView],
    board: &BoardSpec,
    corner_sigma_px: f64,
) -> Result<FloorPlane, CalibError> {
    if views.is_empty() {
        return Err(CalibError::Input(
            "no floor view: lay the board flat on the floor and photograph it".into(),
        ));
    }
    let boards = FloorBoards::locate(camera, views, board, corner_sigma_px)?;
    Ok(boards.plane(&boards.fit_parameters(camera)))
}

/// Two floor boards this far apart across the floor, or turned this far to each other, do not
/// lie on one floor: a real floor is flat to millimetres over a lab, and a board located
/// through a calibrated lens is placed to about a centimetre and a degree even far off the
/// nadir, while a board held in the hand is decimetres above the floor and tilted.
const OFF_PLANE_M: f64 = 0.04;
const OFF_PLANE_TILT_DEG: f64 = 6.0;
/// On a coarse camera a board is placed only to a few pixels' worth of floor: boards this
/// many pixels' footprint apart (at the farther board), when that is more than
/// [`OFF_PLANE_M`], are off one floor. Two correct floor boards of a 480x320 camera 2.6 m up
/// (11 mm of floor a pixel) were put 45 mm apart, calibrated from 6 views.
const OFF_PLANE_PX: f64 = 6.0;

/// How boards `a` and `b` (each located alone) sit against each other: `a`'s centre's height
/// above `b`'s along their mean normal (pointing towards the camera), metres, and the angle
/// between their faces, degrees. The mean normal cancels most of each board's own tilt error.
fn pair_offset(a: (&BoardToCamera, &BoardView), b: (&BoardToCamera, &BoardView)) -> (f64, f64) {
    let centre = |(pose, v): (&BoardToCamera, &BoardView)| {
        let c = v
            .object_points
            .iter()
            .map(|p| p.coords)
            .sum::<Vector3<f64>>()
            / v.object_points.len().max(1) as f64;
        (pose.0 * Point3::from(c)).coords
    };
    let (ca, cb) = (centre(a), centre(b));
    let towards_camera = |pose: &BoardToCamera, c: &Vector3<f64>| {
        let n = pose.0.rotation * Vector3::z();
        if n.dot(c) > 0.0 {
            -n
        } else {
            n
        }
    };
    let (na, nb) = (towards_camera(a.0, &ca), towards_camera(b.0, &cb));
    let tilt_deg = na.dot(&nb).clamp(-1.0, 1.0).acos().to_degrees();
    ((ca - cb).dot(&(na + nb).normalize()), tilt_deg)
}

/// Refuses floor boards that do not lie on one floor (a hand-held view passed as a floor view,
/// or a board propped on something). Each board is compared with every other; the board that
/// agrees with the fewest is named, against the board that agrees with the most.
fn check_on_one_plane(
    camera: &CameraModel,
    pnp: &[BoardToCamera],
    views: &[BoardView],
) -> Result<(), CalibError> {
    let n = pnp.len();
    let off = |a: usize, b: usize| pair_offset((&pnp[a], &views[a]), (&pnp[b], &views[b]));
    let focal_px = camera.intrinsics.fx.max(camera.intrinsics.fy);
    let farthest_m = pnp
        .iter()
        .map(|p| p.0.translation.vector.norm())
        .fold(0.0, f64::max);
    // Only at a ceiling's height: a square given 10 times too large puts the boards 10
    // times too far, and a bound grown with that distance would let their 10 times larger
    // offsets through, where the height check below names --square.
    let height_m = pnp
        .first()
        .map_or(0.0, |p| p.0.inverse().translation.vector.z.abs());
    let off_plane_m = if crate::session::CEILING_HEIGHT_M.contains(&height_m) {
        OFF_PLANE_M.max(OFF_PLANE_PX * farthest_m / focal_px)
    } else {
        OFF_PLANE_M
    };
    let score = |(h, t): (f64, f64)| (h.abs() / off_plane_m).max(t / OFF_PLANE_TILT_DEG);
    let agree = |a: usize, b: usize| score(off(a, b)) <= 1.0;
    let count = |k: usize| (0..n).filter(|&j| j != k && agree(k, j)).count();
    let misfit = |k: usize| {
        (0..n)
            .filter(|&j| j != k)
            .map(|j| score(off(k, j)))
            .sum::<f64>()
    };
    let Some(suspect) = (0..n).filter(|&k| count(k) + 1 < n).min_by(|&a, &b| {
        count(a)
            .cmp(&count(b))
            .then(misfit(b).total_cmp(&misfit(a)))
    }) else {
        return Ok(());
    };
    // The board the suspect is set against is one it disagrees with, the one most others
    // agree with (then the farthest off): naming one it agrees with would give an offset
    // within the bounds the message states.
    let Some(reference) = (0..n)
        .filter(|&j| j != suspect && !agree(suspect, j))
        .max_by(|&a, &b| {
            count(a)
                .cmp(&count(b))
                .then(score(off(suspect, a)).total_cmp(&score(off(suspect, b))))
        })
    else {
        return Ok(());
    };
    let (height_m, tilt_deg) = off(suspect, reference);
    let offset = format!(
        "{:.0} mm {} the other's, tilted {tilt_deg:.1}° to it; boards on one floor are within {:.0} mm and {OFF_PLANE_TILT_DEG:.0}°",
        height_m.abs() * 1e3,
        if height_m > 0.0 { "above" } else { "below" },
        off_plane_m * 1e3,
    );
    // A square given 10 times too large puts every board 10 times too far, and their
    // millimetres of offset read as centimetres: the camera's height says so first.
    let height = pnp[reference].0.inverse().translation.vector.z.abs();
    let ceiling = &crate::session::CEILING_HEIGHT_M;
    if !ceiling.contains(&height) {
        return Err(CalibError::Input(format!(
            "floor views {} and {}: by these boards the camera is {height:.2} m above the floor, outside the {:.1}–{:.0} m of a ceiling camera over small robots, and the boards look {offset}: is --square the side of one square in metres? (a square 10 times too large puts every board 10 times too far, and their small offsets 10 times larger)",
            views[suspect].image,
            views[reference].image,
            ceiling.start(),
            ceiling.end()
        )));
    }
    let advice = "if it is a hand-held view, pass it before --floor; otherwise lay the board flat on the floor and photograph it again";
    Err(CalibError::Input(if n == 2 {
        format!(
            "floor views {} and {}: their boards do not lie on one floor (the first's is {offset}), so one of them is not on the floor; {advice}",
            views[suspect].image, views[reference].image,
        )
    } else {
        format!(
            "floor view {}: its board does not lie on one floor with the board in {} (it is {offset}; it agrees with {} of the other {} floor boards); {advice}",
            views[suspect].image,
            views[reference].image,
            count(suspect),
            n - 1
        )
    }))
}

/// The noise of one board's corners, pixels per coordinate: the calibration's
/// (`corner_sigma_px`), or the board's own residual noise about its PnP pose when that is
/// beyond chance (the 99.9 % point of its variance). One board can be much noisier than the
/// calibration's views: a board whose edges run along the pixel grid has its sub-pixel
/// corners pulled towards pixel positions.
///
/// That pull is alike at neighbouring corners (their sub-pixel phases differ little), so
/// their errors do not average out over the board as independent noise would: on a board
/// laid square to the image, the first floor board of every synthetic seed, the floor frame
/// came out turned by 1.5σ each time. Where neighbours' residuals correlate beyond chance,
/// the noise is scaled up so that the board counts as the fewer independent corners it is
/// worth ([`corner_count_worth`]).
pub(crate) fn board_corner_sigma_px(
    camera: &CameraModel,
    o: &Observation,
    corner_sigma_px: f64,
) -> f64 {
    let own_with_nan = residuals(camera, &o.pose.0, o);
    let own: Vec<f64> = own_with_nan
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    let dof = own.len().saturating_sub(6).max(1) as f64;
    let own_var = own.iter().map(|v| v * v).sum::<f64>() / dof;
    let beyond_chance = 1.0 + 3.1 * (2.0 / dof).sqrt();
    let sigma = if own_var > beyond_chance * corner_sigma_px.powi(2) {
        own_var.sqrt()
    } else {
        corner_sigma_px
    };
    sigma * corner_count_worth(o.object, &own_with_nan).recip().sqrt()
}

/// The share of a board's corners that its residuals (`residuals`' layout: u then v per
/// corner) are worth as independent measurements: 1, or (1 − ρ)/(1 + ρ) where the
/// correlation ρ of neighbouring corners' residual vectors is beyond chance (three times its
/// spread over uncorrelated residuals, 1/√pairs). That is the effective share of a series
/// whose neighbours correlate by ρ, the usual correction for samples that are not
/// independent. Neighbours are corners one square apart on the board.
pub(crate) fn corner_count_worth(object: &[Point3<f64>], residuals: &[f64]) -> f64 {
    let n = object.len().min(residuals.len() / 2);
    let finite = |i: usize| residuals[2 * i].is_finite() && residuals[2 * i + 1].is_finite();
    let step = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .map(|(i, j)| (object[i] - object[j]).norm())
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let (mut products, mut pairs) = (0.0, 0usize);
    for i in (0..n).filter(|&i| finite(i)) {
        for j in (i + 1..n).filter(|&j| finite(j)) {
            if ((object[i] - object[j]).norm() - step).abs() < 0.01 * step {
                products += residuals[2 * i] * residuals[2 * j]
                    + residuals[2 * i + 1] * residuals[2 * j + 1];
                pairs += 1;
            }
        }
    }
    let squares: Vec<f64> = (0..n)
        .filter(|&i| finite(i))
        .map(|i| residuals[2 * i].powi(2) + residuals[2 * i + 1].powi(2))
        .collect();
    let power = squares.iter().sum::<f64>() / squares.len().max(1) as f64;
    if pairs < 4 || power <= 0.0 {
        return 1.0;
    }
    let rho = products / pairs as f64 / power;
    if rho <= 3.0 / (pairs as f64).sqrt() {
        return 1.0;
    }
    let rho = rho.min(0.9);
    (1.0 - rho) / (1.0 + rho)
}

/// Floor boards held on one plane: the unknowns are the floor's pose (a small turn and shift
/// of the starting plane, in its own frame: 6 numbers) and each board's place and turn on the
/// floor (x, y in metres, turn in radians: 3 numbers per board after the first, whose place
/// fixes the floor frame).
pub(crate) struct FloorBoards<'a> {
    /// The floor views, the first fixing the floor frame.
    pub views: &'a [BoardView],
    /// Each board located on its own (solvePnP).
    pub pnp: Vec<BoardToCamera>,
    /// Each board's weight: one over its corners' noise, 1/pixels.
    weight: Vec<f64>,
    /// The floor plane through the PnP boards, where the refinement starts.
    start: Isometry3<f64>,
    /// Each board's rotation into the floor frame at zero turn (its z into the floor).
    base: Vec<UnitQuaternion<f64>>,
    /// The starting parameters.
    pub p0: Vec<f64>,
}

impl<'a> FloorBoards<'a> {
    /// Locates each board by solvePnP and starts the floor at the plane through them all.
    pub fn locate(
        camera: &CameraModel,
        views: &'a [BoardView],
        board: &BoardSpec,
        corner_sigma_px: f64,
    ) -> Result<Self, CalibError> {
        let pnp = views
            .iter()
            .map(|v| board_pose(camera, v, board))
            .collect::<Result<Vec<_>, _>>()?;
        check_on_one_plane(camera, &pnp, views)?;
        let start = plane_from_poses(&pnp, views)?.floor_to_camera.0;
        let weight = pnp
            .iter()
            .zip(views)
            .map(|(pose, v)| {
                let o = Observation {
                    pose: *pose,
                    object: &v.object_points,
                    image: &v.corners,
                };
                1.0 / board_corner_sigma_px(camera, &o, corner_sigma_px).max(1e-6)
            })
            .collect();
        let mut base = Vec::with_capacity(pnp.len());
        let mut p0 = vec![0.0; 6];
        for (k, pose) in pnp.iter().enumerate() {
            let on_floor = start.inverse() * pose.0;
            let z = on_floor.rotation * Vector3::z();
            let b = if z.z < 0.0 {
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
            } else {
                UnitQuaternion::identity()
            };
            base.push(b);
            if k > 0 {
                let x = on_floor.rotation * Vector3::x();
                let t = on_floor.translation.vector;
                p0.extend([t.x, t.y, x.y.atan2(x.x)]);
            }
        }
        Ok(Self {
            views,
            pnp,
            weight,
            start,
            base,
            p0,
        })
    }

    /// The floor pose of parameters `p`.
    pub fn floor(&self, p: &[f64]) -> FloorToCamera {
        let turn = UnitQuaternion::from_scaled_axis(Vector3::new(p[0], p[1], p[2]));
        FloorToCamera(self.start * Isometry3::from_parts(Translation3::new(p[3], p[4], p[5]), turn))
    }

    /// Board `k`'s pose in the floor frame for parameters `p`.
    pub(crate) fn board_to_floor(&self, p: &[f64], k: usize) -> Isometry3<f64> {
        if k == 0 {
            return Isometry3::from_parts(Translation3::identity(), self.base[0]);
        }
        let q = &p[6 + 3 * (k - 1)..6 + 3 * k];
        Isometry3::from_parts(
            Translation3::new(q[0], q[1], 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q[2]) * self.base[k],
        )
    }

    /// Every corner's reprojection error over its noise (x, y in turn), with camera `camera`
    /// and parameters `p`; NaN where a corner falls behind the camera.
    pub fn weighted_residuals(&self, camera: &CameraModel, p: &[f64]) -> Vec<f64> {
        self.board_residuals_px(camera, p)
            .iter()
            .zip(&self.weight)
            .flat_map(|(r, w)| r.iter().map(move |e| e * w))
            .collect()
    }

    /// Each board's reprojection errors held on the floor of parameters `p`, pixels (x, y in
    /// turn); NaN where a corner falls behind the camera.
    pub(crate) fn board_residuals_px(&self, camera: &CameraModel, p: &[f64]) -> Vec<Vec<f64>> {
        let floor = self.floor(p).0;
        self.views
            .iter()
            .enumerate()
            .map(|(k, v)| {
                let pose = floor * self.board_to_floor(p, k);
                let o = Observation {
                    pose: BoardToCamera(pose),
                    object: &v.object_points,
                    image: &v.corners,
                };
                residuals(camera, &pose, &o)
            })
            .collect()
    }

    /// The floor plane of parameters `p`, with the PnP corners' scatter about it (which says
    /// how flat the floor and boards are).
    pub fn plane(&self, p: &[f64]) -> FloorPlane {
        let floor = self.floor(p);
        let up = floor.0.rotation * Vector3::z();
        let origin = floor.0.translation.vector;
        let pnp: Vec<Vector3<f64>> = self
            .pnp
            .iter()
            .zip(self.views)
            .flat_map(|(pose, v)| v.object_points.iter().map(|p| (pose.0 * p).coords))
            .collect();
        let plane_rms_m = (pnp
            .iter()
            .map(|p| (p - origin).dot(&up).powi(2))
            .sum::<f64>()
            / pnp.len().max(1) as f64)
            .sqrt();
        FloorPlane {
            floor_to_camera: floor,
            plane_rms_m,
            camera_height_m: -origin.dot(&up),
            views: self.views.iter().map(|v| v.image.clone()).collect(),
        }
    }

    /// The parameters of the floor that best reprojects every board's corners, held on one
    /// plane; the PnP start if the refinement fails.
    pub fn fit_parameters(&self, camera: &CameraModel) -> Vec<f64> {
        let f = |p: &[f64]| self.weighted_residuals(camera, p);
        let (p, report) = odocal_core::lsq::minimize(&f, self.p0.clone(), 200);
        let cost = |p: &[f64]| f(p).iter().map(|v| v * v).sum::<f64>();
        if report.termination.was_successful() && cost(&p) <= cost(&self.p0) {
            p
        } else {
            self.p0.clone()
        }
    }
}

/// The floor plane through boards lying on the floor, located at `poses` (one per view):
/// the least-squares plane of all their corners, its origin at the first board's first
/// corner and its x axis along that board's rows.
pub(crate) fn plane_from_poses(
    poses: &[BoardToCamera],
    views: &[BoardView],
) -> Result<FloorPlane, CalibError> {
    let mut pts: Vec<Point3<f64>> = Vec::new();
    for (pose, v) in poses.iter().zip(views) {
        pts.extend(v.object_points.iter().map(|p| pose.0 * p));
    }
    let Some(&first_pose) = poses.first() else {
        return Err(CalibError::Input("no floor view".into()));
    };
    if !pts.iter().all(|p| p.coords.iter().all(|v| v.is_finite())) {
        return Err(CalibError::Input(
            "a floor board could not be located (its pose is not finite)".into(),
        ));
    }
    let n = pts.len() as f64;
    let centroid = pts.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n;
    let mut scatter = Matrix3::zeros();
    for p in &pts {
        let d = p.coords - centroid;
        scatter += d * d.transpose();
    }
    let eig = scatter.symmetric_eigen();
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |b, (i, &v)| if v < b.1 { (i, v) } else { b },
        );
    let mut up = eig.eigenvectors.column(imin).into_owned().normalize();
    // "Up" points from the floor towards the camera (the camera origin).
    if up.dot(&(-centroid)) < 0.0 {
        up = -up;
    }
    let plane_rms_m = (pts
        .iter()
        .map(|p| (p.coords - centroid).dot(&up).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    // Origin: the first view's first corner, dropped onto the plane.
    let o = first_pose.0.translation.vector;
    let origin = o - up * (o - centroid).dot(&up);
    let bx = first_pose.0.rotation * Vector3::x();
    let x = (bx - up * bx.dot(&up)).normalize();
    let y = up.cross(&x);
    let rot = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, up]));
    let floor_to_camera = FloorToCamera(Isometry3::from_parts(
        Translation3::from(origin),
        UnitQuaternion::from_rotation_matrix(&rot),
    ));
    let camera_height_m = (-centroid).dot(&up);
    Ok(FloorPlane {
        floor_to_camera,
        plane_rms_m,
        camera_height_m,
        views: views.iter().map(|v| v.image.clone()).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// A 9x6 grid of corners 5 cm apart, and residuals made by `at(col, row)`.
    fn grid(at: impl Fn(usize, usize) -> (f64, f64)) -> (Vec<Point3<f64>>, Vec<f64>) {
        let mut object = Vec::new();
        let mut r = Vec::new();
        for row in 0..6 {
            for col in 0..9 {
                object.push(Point3::new(col as f64 * 0.05, row as f64 * 0.05, 0.0));
                let (u, v) = at(col, row);
                r.extend([u, v]);
            }
        }
        (object, r)
    }

    #[test]
    fn corners_count_as_fewer_where_neighbours_err_alike() {
        // Independent noise: every corner counts, on each of 20 draws.
        let noise = Normal::new(0.0, 0.03).unwrap();
        for seed in 0..20 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut draws = vec![0.0; 108];
            for d in &mut draws {
                *d = noise.sample(&mut rng);
            }
            let (object, r) =
                grid(|c, row| (draws[2 * (row * 9 + c)], draws[2 * (row * 9 + c) + 1]));
            assert_eq!(corner_count_worth(&object, &r), 1.0, "seed {seed}");
        }
        // A pull that drifts slowly over the board (sub-pixel phases drifting along a board
        // laid nearly square to the pixel grid): each coordinate's error is the same down a
        // column or along a row, and turns by 0.6 rad to the next corner the other way, so
        // neighbours correlate by about 0.9 and the board is worth about a twentieth of its
        // corners.
        let (object, r) =
            grid(|c, row| ((c as f64 * 0.6).sin() * 0.1, (row as f64 * 0.6).cos() * 0.1));
        let worth = corner_count_worth(&object, &r);
        assert!((0.03..0.1).contains(&worth), "{worth}");
        // Errors alternating from corner to corner average out faster than noise: no credit.
        let (object, r) = grid(|c, row| (if (c + row) % 2 == 0 { 0.1 } else { -0.1 }, 0.0));
        assert_eq!(corner_count_worth(&object, &r), 1.0);
        // Corners not projected (NaN) are left out, not counted as errors.
        let (object, mut r) =
            grid(|c, row| ((c as f64 * 0.6).sin() * 0.1, (row as f64 * 0.6).cos() * 0.1));
        r[0] = f64::NAN;
        r[1] = f64::NAN;
        assert!((corner_count_worth(&object, &r) - worth).abs() < 0.1);
    }
}
