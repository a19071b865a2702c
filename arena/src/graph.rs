//! The arena's pose graph: every camera's pose in the floor frame and every shared board's
//! place on the floor, fitted together to the boards' corners in every image.
//!
//! Unknowns: each camera's pose but the first's (six numbers: a small rotation and a
//! translation applied to its first guess) and each shared board's place (x, y and a turn
//! about the vertical: the board lies on the floor, a hard constraint rather than a prior).
//! The first camera keeps the floor pose its own calibration gave, so the arena's floor frame
//! is that camera's: the origin and axes of its first floor board. The residuals are the
//! corners' pixel errors in every camera that saw the board, minimised by
//! Levenberg–Marquardt (`odocal_core::lsq`). The first guess chains solvePnP poses from the
//! first camera through the shared views.
//!
//! Corner numbering: a ChArUco board names every corner, so any cameras agree on it. OpenCV
//! numbers a plain checkerboard's corners from the one nearest the image's top-left, so two
//! cameras name its corners alike only when their images are turned alike (within ±45° about
//! the vertical). Cameras mounted otherwise number them differently; the fit then cannot make
//! them agree, and the consistency check refuses the result.

use nalgebra::{DMatrix, Isometry3, Point2, Translation3, UnitQuaternion, Vector3};
use odocal_calib::{board_pose, BoardSpec, CameraFile, CameraModel, FloorToCamera};
use rayon::prelude::*;
use std::path::Path;

use crate::{ArenaError, Consistency, PairConsistency, SharedView};

/// Two cameras disagreeing by more than this (RMS over the shared corners, millimetres) means
/// the fit failed (corners numbered differently, a board moved between shots, a wrong
/// calibration): the arena is refused.
pub const REFUSE_RMS_MM: f64 = 20.0;

/// One camera's image of one shared board, as the fit uses it.
#[derive(Debug, Clone, PartialEq)]
pub struct SharedObservation {
    /// Index of the shared view.
    pub view: usize,
    /// Index of the camera.
    pub camera: usize,
    /// The detected inner corners, pixels.
    pub corners: Vec<Point2<f64>>,
    /// Each corner's index among the board's inner corners (a ChArUco board's ids).
    pub ids: Vec<u32>,
    /// Each corner's place on the board (board frame), metres.
    pub object_points: Vec<nalgebra::Point3<f64>>,
}

/// The fitted arena.
#[derive(Debug, Clone, PartialEq)]
pub struct ArenaSolution {
    /// Each camera's pose: maps the arena's floor frame into the camera frame.
    pub arena_to_camera: Vec<FloorToCamera>,
    /// Each shared board's pose: maps board points into the arena's floor frame.
    pub board_to_arena: Vec<Isometry3<f64>>,
    /// RMS pixel residual of each camera's shared-view corners, pixels.
    pub rms_px: Vec<f64>,
    /// Shared views each camera took part in.
    pub views_per_camera: Vec<usize>,
    /// Agreement of all pairs over the shared boards.
    pub consistency: Consistency,
    /// Agreement of each pair that shares a board.
    pub pairs: Vec<PairConsistency>,
    /// Each camera's joint covariance of its pose correction and its intrinsics
    /// ([`crate::ArenaCamera::pose_covariance`]).
    pub pose_covariance: Vec<Option<DMatrix<f64>>>,
    /// How well the floor frame is placed ([`crate::ArenaFile::frame_placement`]).
    pub frame_placement: Option<crate::FramePlacement>,
    /// The cameras whose shared images numbered the checkerboard's corners from the other end
    /// (mounted turned about 180° from the first camera), read with their numbering turned
    /// back; None when every camera's numbering was taken as recorded.
    pub renumbered: Option<Renumbered>,
}

/// The cameras whose checkerboard corners were read numbered from the other end.
#[derive(Debug, Clone, PartialEq)]
pub struct Renumbered {
    /// The cameras' indices, in order.
    pub cameras: Vec<usize>,
    /// How far apart the cameras put the shared corners as the images numbered them, mm RMS.
    pub numbered_as_recorded_mm: f64,
}

/// A board lying face up on the floor at (x, y) turned by `yaw_rad`: its z axis points into
/// the floor.
fn board_on_floor(x: f64, y: f64, yaw_rad: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_rad)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
    )
}

/// The board's place on the floor (x, y, yaw) closest to a full pose.
fn floor_place(board_to_arena: &Isometry3<f64>) -> [f64; 3] {
    let x = board_to_arena.rotation * Vector3::x();
    let t = board_to_arena.translation.vector;
    [t.x, t.y, x.y.atan2(x.x)]
}

pub(crate) fn camera_pose(init: &FloorToCamera, p: &[f64]) -> Isometry3<f64> {
    let delta = Isometry3::from_parts(
        Translation3::new(p[3], p[4], p[5]),
        UnitQuaternion::from_scaled_axis(Vector3::new(p[0], p[1], p[2])),
    );
    delta * init.0
}

/// Fits the arena from the camera files (the first must have its floor plane) and the shared
/// views. The board is the one every shared view shows.
pub fn solve_arena(
    cameras: &[CameraFile],
    camera_paths: &[&Path],
    shared: &[SharedView],
    board: &BoardSpec,
) -> Result<ArenaSolution, ArenaError> {
    let n = cameras.len();
    if n < 2 {
        return Err(ArenaError::Input(
            "an arena needs at least two --camera files".into(),
        ));
    }
    let first_floor = *cameras[0].require_floor(camera_paths[0])?;
    let models: Vec<CameraModel> = cameras.iter().map(|c| c.camera).collect();
    let mut fit = fit_graph(&models, first_floor, camera_paths, shared, board, PATIENCE)?;
    let mut renumbered = None;
    if fit.consistency.rms_mm > REFUSE_RMS_MM {
        // A camera mounted turned 180° from the first numbers every checkerboard's corners
        // from the other end; both numberings are the same board, and the one that makes the
        // cameras agree is the board as it lay.
        let turned_back = turned_cameras(&models, first_floor, camera_paths, shared, board)
            .and_then(|set| {
                let f = fit_graph(
                    &models,
                    first_floor,
                    camera_paths,
                    &numbered_back(shared, &set),
                    board,
                    PATIENCE,
                )
                .ok()?;
                (f.consistency.rms_mm <= REFUSE_RMS_MM).then_some((set, f))
            });
        let Some((set, f)) = turned_back else {
            return Err(ArenaError::Refused(disagreement(
                &models,
                first_floor,
                camera_paths,
                shared,
                board,
                &fit,
            )));
        };
        renumbered = Some(Renumbered {
            cameras: set,
            numbered_as_recorded_mm: fit.consistency.rms_mm,
        });
        fit = f;
    }
    let GraphFit {
        cams,
        boards,
        observations,
        residuals: r,
        consistency,
        pairs,
    } = fit;
    let mut sq = vec![0.0; n];
    let mut count = vec![0usize; n];
    let mut views_per_camera = vec![0usize; n];
    let mut at = 0;
    for o in &observations {
        let m = 2 * o.corners.len();
        sq[o.camera] += r[at..at + m].iter().map(|v| v * v).sum::<f64>();
        at += m;
        count[o.camera] += o.corners.len();
        views_per_camera[o.camera] += 1;
    }
    let rms_px: Vec<f64> = sq
        .iter()
        .zip(&count)
        .map(|(s, c)| if *c > 0 { (s / *c as f64).sqrt() } else { 0.0 })
        .collect();
    let pose_covariance = pose_covariances(cameras, &cams, &boards, &observations);
    let arena_to_camera: Vec<FloorToCamera> = cams.into_iter().map(FloorToCamera).collect();
    check_residuals(cameras, camera_paths, &rms_px)?;
    Ok(ArenaSolution {
        arena_to_camera,
        board_to_arena: boards,
        rms_px,
        views_per_camera,
        consistency,
        pairs,
        pose_covariance,
        frame_placement: frame_placement(&cameras[0]),
        renumbered,
    })
}

/// The shared views with the checkerboard corners of the `cameras` numbered from the other
/// end.
fn numbered_back(shared: &[SharedView], cameras: &[usize]) -> Vec<SharedView> {
    shared
        .iter()
        .map(|s| {
            let mut s = s.clone();
            for (_, bv) in s.views.iter_mut().filter(|(c, _)| cameras.contains(c)) {
                bv.corners.reverse();
            }
            s
        })
        .collect()
}

/// The pose graph fitted to some shared views, before any judgement of it.
struct GraphFit {
    cams: Vec<Isometry3<f64>>,
    boards: Vec<Isometry3<f64>>,
    observations: Vec<SharedObservation>,
    residuals: Vec<f64>,
    consistency: Consistency,
    pairs: Vec<PairConsistency>,
}

/// Fits every camera's pose (the first kept at `first_floor`) and every view's board place.
fn fit_graph(
    models: &[CameraModel],
    first_floor: FloorToCamera,
    camera_paths: &[&Path],
    shared: &[SharedView],
    board: &BoardSpec,
    patience: usize,
) -> Result<GraphFit, ArenaError> {
    let n = models.len();
    // First guesses: solvePnP of every image, chained from the first camera.
    let mut pnp = Vec::new();
    for (s, view) in shared.iter().enumerate() {
        for (k, bv) in &view.views {
            pnp.push((s, *k, board_pose(&models[*k], bv, board)?, bv));
        }
    }
    let mut cam_init: Vec<Option<FloorToCamera>> = vec![None; n];
    cam_init[0] = Some(first_floor);
    let mut board_init: Vec<Option<[f64; 3]>> = vec![None; shared.len()];
    loop {
        let mut progress = false;
        for (s, k, pose, _) in &pnp {
            if let (Some(cam), None) = (cam_init[*k], board_init[*s]) {
                board_init[*s] = Some(floor_place(&(cam.0.inverse() * pose.0)));
                progress = true;
            }
        }
        for (s, k, pose, _) in &pnp {
            if let (None, Some([x, y, yaw])) = (cam_init[*k], board_init[*s]) {
                cam_init[*k] = Some(FloorToCamera(pose.0 * board_on_floor(x, y, yaw).inverse()));
                progress = true;
            }
        }
        if !progress {
            break;
        }
    }
    let unlinked: Vec<String> = cam_init
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_none())
        .map(|(k, _)| format!("{k} ({})", camera_paths[k].display()))
        .collect();
    if let [rest @ .., last] = unlinked.as_slice() {
        let (who, verb) = if rest.is_empty() {
            (format!("camera {last}"), "shares")
        } else {
            (format!("cameras {} and {last}", rest.join(", ")), "share")
        };
        return Err(ArenaError::Input(format!(
            "{who} {verb} no board with the first camera, directly or through others: photograph a board on the floor where its view overlaps another's, with both cameras at once",
        )));
    }
    let cam_init: Vec<FloorToCamera> = cam_init.into_iter().flatten().collect();
    let board_init: Vec<[f64; 3]> = board_init.into_iter().flatten().collect();
    let observations: Vec<SharedObservation> = pnp
        .into_iter()
        .map(|(view, camera, _, bv)| SharedObservation {
            view,
            camera,
            corners: bv.corners.clone(),
            ids: bv.ids.clone(),
            object_points: bv.object_points.clone(),
        })
        .collect();
    let n_cam = 6 * (n - 1);
    let n_residuals: usize = observations.iter().map(|o| 2 * o.corners.len()).sum();
    let unpack = |p: &[f64]| -> (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>) {
        let cams = (0..n)
            .map(|k| {
                if k == 0 {
                    cam_init[0].0
                } else {
                    camera_pose(&cam_init[k], &p[6 * (k - 1)..6 * k])
                }
            })
            .collect();
        let boards = (0..board_init.len())
            .map(|s| {
                let q = &p[n_cam + 3 * s..n_cam + 3 * s + 3];
                board_on_floor(q[0], q[1], q[2])
            })
            .collect();
        (cams, boards)
    };
    let residuals = |p: &[f64]| -> Vec<f64> {
        let (cams, boards) = unpack(p);
        pixel_residuals(models, &cams, &boards, &observations, n_residuals)
    };
    let mut p0 = vec![0.0; n_cam];
    for b in &board_init {
        p0.extend_from_slice(b);
    }
    let (p, _report) = odocal_core::lsq::minimize(&residuals, p0, patience);
    let (cams, boards) = unpack(&p);
    let r = residuals(&p);
    let poses: Vec<FloorToCamera> = cams.iter().copied().map(FloorToCamera).collect();
    let (consistency, pairs) = consistency(models, &poses, &observations)?;
    Ok(GraphFit {
        cams,
        boards,
        observations,
        residuals: r,
        consistency,
        pairs,
    })
}

/// Shared views that agree within this once the disagreeing ones are left out (RMS, mm) are
/// sound: a fitted arena agrees within about 1 mm (0.67 mm on the synthetic arena).
const AGREE_MM: f64 = 5.0;
/// The fit's patience (Levenberg–Marquardt evaluations per parameter).
const PATIENCE: usize = 200;
/// A trial fit of the search ends sooner: views that agree start near their fit and converge
/// within a few evaluations, and where nothing agrees (a wrong --square) a full fit of each
/// trial took minutes.
const TRIAL_PATIENCE: usize = 5;

/// The views tried in each round of the search: the worst fitting over all views.
const CANDIDATES: usize = 3;

/// Each view's corners' RMS pixel residual in `fit`.
fn view_rms_px(fit: &GraphFit, views: usize) -> Vec<f64> {
    let mut sq = vec![0.0; views];
    let mut count = vec![0usize; views];
    let mut at = 0;
    for o in &fit.observations {
        let m = 2 * o.corners.len();
        if let (Some(s), Some(r)) = (sq.get_mut(o.view), fit.residuals.get(at..at + m)) {
            *s += r.iter().map(|v| v * v).sum::<f64>();
            count[o.view] += o.corners.len();
        }
        at += m;
    }
    sq.iter()
        .zip(&count)
        .map(|(s, &c)| if c > 0 { (s / c as f64).sqrt() } else { 0.0 })
        .collect()
}

/// Each view left out must bring the others' disagreement (RMS) below this share of what it
/// was (a misnamed image's view takes 186 mm to 0.68 mm); a wrong --square leaves 4 m.
const STEP_GAIN: f64 = 0.7;
/// One image's board within this of another view's (the farthest of the board's outer
/// corners, metres) shows that view's board: its place is known to about a millimetre.
const SAME_PLACE_M: f64 = 0.01;

/// Why the shared views disagree: the views whose leaving out (greedily, at most a third of
/// them, each camera still tied) makes the rest agree within [`AGREE_MM`] are named, and each
/// of their images whose board lies where another view's does is named as that view's. A
/// misnamed image disagrees by tens of centimetres and the consistency over all views
/// cannot say which it is.
fn disagreement(
    models: &[CameraModel],
    first_floor: FloorToCamera,
    camera_paths: &[&Path],
    shared: &[SharedView],
    board: &BoardSpec,
    full: &GraphFit,
) -> String {
    let all = &full.consistency;
    // The views whose corners fit worst over all views are the ones tried: each trial is a
    // fit of its own, and a refusal waits for them.
    let mut worst: Vec<(usize, f64)> = view_rms_px(full, shared.len())
        .into_iter()
        .enumerate()
        .collect();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1));
    let generic = format!(
        "the cameras put the shared boards' corners {:.1} mm apart (RMS; refused above {REFUSE_RMS_MM} mm): check that every camera file belongs to its _cK images, that the board did not move between the cameras' shots, and that the cameras' images are turned alike (within 45°), so that they number the corners alike",
        all.rms_mm
    );
    let kept = |out: &[usize]| -> Vec<SharedView> {
        (0..shared.len())
            .filter(|s| !out.contains(s))
            .map(|s| shared[s].clone())
            .collect()
    };
    let mut out: Vec<usize> = Vec::new();
    let mut rest = None;
    while out.len() < shared.len() / 3 {
        // Every candidate is a fit of its own: in parallel, since a refusal waits for them.
        let candidates: Vec<usize> = worst
            .iter()
            .map(|&(s, _)| s)
            .filter(|s| !out.contains(s))
            .take(CANDIDATES)
            .collect();
        let best = candidates
            .into_par_iter()
            .filter_map(|s| {
                let trial = [out.as_slice(), &[s]].concat();
                let f = fit_graph(
                    models,
                    first_floor,
                    camera_paths,
                    &kept(&trial),
                    board,
                    TRIAL_PATIENCE,
                )
                .ok()?;
                Some((s, f))
            })
            .min_by(|a, b| a.1.consistency.rms_mm.total_cmp(&b.1.consistency.rms_mm));
        let Some((s, f)) = best else { break };
        // A view that is not alone at fault (a wrong --square, another camera's file) leaves
        // the rest disagreeing nearly as much: searching on would only cost fits.
        let before_mm = rest
            .as_ref()
            .map_or(all.rms_mm, |r: &GraphFit| r.consistency.rms_mm);
        if f.consistency.rms_mm > STEP_GAIN * before_mm {
            break;
        }
        out.push(s);
        let sound = f.consistency.rms_mm <= AGREE_MM;
        rest = Some(f);
        if sound {
            break;
        }
    }
    let Some(rest) = rest.filter(|f| f.consistency.rms_mm <= AGREE_MM) else {
        return generic;
    };
    out.sort_unstable();
    let kept_views = kept(&out);
    // Where each image puts its board with the cameras the other views fitted.
    let place = |k: usize, bv: &odocal_calib::BoardView| {
        board_pose(&models[k], bv, board)
            .ok()
            .map(|p| rest.cams[k].inverse() * p.0)
    };
    // What an image's board may be mistaken for: the other views' boards where they agree,
    // and the other left-out images (two images swapped between views match each other's).
    let mut known: Vec<(&str, String, Isometry3<f64>)> = kept_views
        .iter()
        .zip(&rest.boards)
        .map(|(v, b)| (v.name.as_str(), format!("view {}", v.name), *b))
        .collect();
    for &s in &out {
        for (k, bv) in &shared[s].views {
            if let Some(p) = place(*k, bv) {
                known.push((shared[s].name.as_str(), bv.image.clone(), p));
            }
        }
    }
    let mut found = Vec::new();
    for &s in &out {
        let view = &shared[s];
        let elsewhere: Vec<String> = view
            .views
            .iter()
            .filter_map(|(k, bv)| {
                let p = place(*k, bv)?;
                let apart = |q: &Isometry3<f64>| board_apart_m(&p, q, board);
                let (_, other, _) = known
                    .iter()
                    .filter(|(name, _, q)| *name != view.name && apart(q) < SAME_PLACE_M)
                    .min_by(|a, b| apart(&a.2).total_cmp(&apart(&b.2)))?;
                Some(format!("{} shows the board where {other} has it", bv.image))
            })
            .collect();
        let images: Vec<&str> = view.views.iter().map(|(_, bv)| bv.image.as_str()).collect();
        let spread_mm = view
            .views
            .iter()
            .filter_map(|(k, bv)| place(*k, bv))
            .collect::<Vec<_>>()
            .windows(2)
            .map(|w| board_apart_m(&w[0], &w[1], board) * 1e3)
            .fold(0.0, f64::max);
        found.push(if elsewhere.is_empty() {
            format!(
                "view {} ({}: their boards {spread_mm:.0} mm apart)",
                view.name,
                images.join(", ")
            )
        } else {
            format!("view {} ({})", view.name, elsewhere.join("; "))
        });
    }
    format!(
        "the cameras put the shared boards' corners {:.1} mm apart (RMS; refused above {REFUSE_RMS_MM} mm), but without {} the other {} views agree within {:.2} mm: {}: check that each image is saved under its own view's name (a misnamed, copied or swapped image), that the board did not move between the cameras' shots of a view, and that its images are turned alike (within 45°), so that the cameras number the corners alike; rename the images, or take that view again (or leave its images out of --shared)",
        all.rms_mm,
        if out.len() == 1 { "one view" } else { "some views" },
        kept_views.len(),
        rest.consistency.rms_mm,
        found.join("; ")
    )
}

/// Sets of the other cameras tried turned, at most: every set up to seven cameras (63 fits),
/// beyond that sets of one and two.
const TURNED_SETS_ALL_UP_TO: usize = 6;

/// The cameras whose shared images, numbered from the other end, make every camera agree
/// within [`AGREE_MM`] (cameras turned about 180° from the first), fewest first (of sets as
/// few, the one that agrees best); None for a ChArUco board (its corners are named, not
/// numbered) or when no set does.
fn turned_cameras(
    models: &[CameraModel],
    first_floor: FloorToCamera,
    camera_paths: &[&Path],
    shared: &[SharedView],
    board: &BoardSpec,
) -> Option<Vec<usize>> {
    if board.target != odocal_calib::BoardTarget::Checkerboard {
        return None;
    }
    // The first camera is the one the others are turned from.
    let others = models.len().saturating_sub(1);
    let largest = if others <= TURNED_SETS_ALL_UP_TO {
        others
    } else {
        2
    };
    (1..=largest).find_map(|size| {
        let sets: Vec<Vec<usize>> = (1u64..(1u64 << others.min(63)))
            .filter(|bits| bits.count_ones() as usize == size)
            .map(|bits| (1..=others).filter(|k| bits >> (k - 1) & 1 == 1).collect())
            .collect();
        sets.into_par_iter()
            .filter_map(|set| {
                let f = fit_graph(
                    models,
                    first_floor,
                    camera_paths,
                    &numbered_back(shared, &set),
                    board,
                    TRIAL_PATIENCE,
                )
                .ok()?;
                Some((set, f.consistency.rms_mm))
            })
            .filter(|(_, rms_mm)| *rms_mm <= AGREE_MM)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(set, _)| set)
    })
}

/// How far apart two places of one board put it: the farthest of its outer corners, metres.
fn board_apart_m(a: &Isometry3<f64>, b: &Isometry3<f64>, board: &BoardSpec) -> f64 {
    let (w, h) = (
        f64::from(board.cols.saturating_sub(1)) * board.square_m,
        f64::from(board.rows.saturating_sub(1)) * board.square_m,
    );
    [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .iter()
        .map(|&(x, y)| {
            let q = nalgebra::Point3::new(x, y, 0.0);
            (a * q - b * q).norm()
        })
        .fold(0.0, f64::max)
}

/// The corners' pixel residuals of every observation with these cameras and board places.
fn pixel_residuals(
    models: &[CameraModel],
    cams: &[Isometry3<f64>],
    boards: &[Isometry3<f64>],
    observations: &[SharedObservation],
    n_residuals: usize,
) -> Vec<f64> {
    let mut r = Vec::with_capacity(n_residuals);
    for o in observations {
        let to_cam = cams[o.camera] * boards[o.view];
        for (q, seen) in o.object_points.iter().zip(&o.corners) {
            match models[o.camera].project(&(to_cam * q)) {
                Some(px) => {
                    r.push(px.x - seen.x);
                    r.push(px.y - seen.y);
                }
                None => {
                    r.push(1e3);
                    r.push(1e3);
                }
            }
        }
    }
    r
}

/// Central-difference Jacobian of `f` at `p` (steps `h[i]`), as columns.
fn jacobian(f: &dyn Fn(&[f64]) -> Vec<f64>, p: &[f64], h: &[f64]) -> DMatrix<f64> {
    let cols: Vec<Vec<f64>> = (0..p.len())
        .map(|i| {
            let (mut a, mut b) = (p.to_vec(), p.to_vec());
            a[i] += h[i];
            b[i] -= h[i];
            let (ra, rb) = (f(&a), f(&b));
            ra.iter()
                .zip(&rb)
                .map(|(x, y)| (x - y) / (2.0 * h[i]))
                .collect()
        })
        .collect();
    let m = cols.first().map_or(0, Vec::len);
    DMatrix::from_fn(m, cols.len(), |r, c| cols[c][r])
}

/// For every camera but the first, the joint covariance of a small correction to its fitted
/// pose (rotation vector and translation, applied before it as in `camera_pose`) and of its
/// intrinsics (`CameraModel::parameters`), linearised at the fit.
///
/// A camera's pose is fitted with every camera's intrinsics held at their calibrated values,
/// so each calibration's error moves the fitted poses: through the shared boards, a
/// neighbour's error becomes this camera's, the same for every fix in a region, and this
/// camera's own error is partly made good by its pose where the boards tie it. The
/// covariance carries the intrinsics' covariances (camera.json's) through the fit, plus the
/// corners' noise. The first camera's pose is its own floor's, located with those same
/// intrinsics from its floor boards: the fit here cannot move it, but its uncertainty (the
/// floor's joint covariance with the intrinsics, kept in its floor uncertainty map) moves the
/// arena's floor frame, and with it every camera tied to it; a camera file without it has its
/// intrinsics' error taken up by the rigid move of the first camera that best absorbs it.
/// The first camera itself is left out: its floor uncertainty map already describes how its
/// pixels reach the floor. None for a camera whose file has no covariance, or when the fit's
/// normal matrix is singular.
fn pose_covariances(
    files: &[CameraFile],
    cams: &[Isometry3<f64>],
    boards: &[Isometry3<f64>],
    observations: &[SharedObservation],
) -> Vec<Option<DMatrix<f64>>> {
    let n = cams.len();
    let models: Vec<CameraModel> = files.iter().map(|c| c.camera).collect();
    let m: usize = observations.iter().map(|o| 2 * o.corners.len()).sum();
    let n_cam = 6 * (n - 1);
    let places: Vec<[f64; 3]> = boards.iter().map(floor_place).collect();
    let unpack = |p: &[f64]| -> (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>) {
        let c = (0..n)
            .map(|k| match k {
                0 => cams[0],
                _ => camera_pose(&FloorToCamera(cams[k]), &p[6 * (k - 1)..6 * k]),
            })
            .collect();
        let b = (0..places.len())
            .map(|s| {
                let (q, at) = (&p[n_cam + 3 * s..n_cam + 3 * s + 3], places[s]);
                board_on_floor(at[0] + q[0], at[1] + q[1], at[2] + q[2])
            })
            .collect();
        (c, b)
    };
    let np = n_cam + 3 * places.len();
    let f = |p: &[f64]| {
        let (c, b) = unpack(p);
        pixel_residuals(&models, &c, &b, observations, m)
    };
    let j = jacobian(&f, &vec![0.0; np], &vec![1e-6; np]);
    let Some(normal_inv) = (j.transpose() * &j).try_inverse() else {
        return vec![None; n];
    };
    let r = f(&vec![0.0; np]);
    let s2 = r.iter().map(|v| v * v).sum::<f64>() / m.saturating_sub(np).max(1) as f64;
    let solve = &normal_inv * j.transpose();
    // Each calibrated camera's intrinsics: how the fitted parameters move with them.
    let moved: Vec<Option<(DMatrix<f64>, DMatrix<f64>)>> = (0..n)
        .map(|k| {
            let cov = files[k].covariance_matrix()?;
            let p0 = models[k].parameters();
            if cov.nrows() != p0.len() {
                return None;
            }
            let g = |q: &[f64]| {
                let mut ms = models.clone();
                ms[k] = models[k].with_parameters(q);
                pixel_residuals(&ms, cams, boards, observations, m)
            };
            let h: Vec<f64> = p0.iter().map(|v| 1e-6 * v.abs().max(1e-3)).collect();
            let mut j_int = jacobian(&g, &p0, &h);
            if let Some(joint) = (k == 0)
                .then(|| first_floor_covariance(&files[0]))
                .flatten()
            {
                // The arena's floor frame is the first camera's floor, located from its floor
                // boards: where it is uncertain, every camera tied to it is moved with it, far
                // from the first camera's image as much as in it (a turn of the frame about
                // its origin moves a camera 3 m off by 3 mm a milliradian).
                let moved_floor = |d: &[f64]| {
                    let mut c = cams.to_vec();
                    c[0] = cams[0] * floor_correction(d);
                    pixel_residuals(&models, &c, boards, observations, m)
                };
                let j_floor = jacobian(&moved_floor, &[0.0; 6], &[1e-6; 6]);
                let mut j = DMatrix::zeros(j_int.nrows(), 6 + j_int.ncols());
                j.columns_mut(0, 6).copy_from(&j_floor);
                j.columns_mut(6, j_int.ncols()).copy_from(&j_int);
                return Some((-(&solve * j), joint));
            }
            if k == 0 {
                // The first camera's pose is its own floor's, located with the same
                // intrinsics: it takes up what a rigid move can of their error.
                let turn = |d: &[f64]| {
                    let mut c = cams.to_vec();
                    c[0] = camera_pose(&FloorToCamera(cams[0]), d);
                    pixel_residuals(&models, &c, boards, observations, m)
                };
                let j_pose = jacobian(&turn, &[0.0; 6], &[1e-6; 6]);
                let fit = (j_pose.transpose() * &j_pose).try_inverse()?;
                j_int -= &j_pose * (fit * j_pose.transpose() * &j_int);
            }
            Some((-(&solve * j_int), cov))
        })
        .collect();
    (0..n)
        .map(|k| {
            let (_, own) = moved.get(k)?.as_ref()?;
            let rows = 6 * k.checked_sub(1)?..6 * k;
            let ni = own.nrows();
            let mut c = DMatrix::zeros(6 + ni, 6 + ni);
            let mut pose = normal_inv.view((rows.start, rows.start), (6, 6)) * s2;
            for (sens, cov) in moved.iter().flatten() {
                let s = sens.rows(rows.start, 6);
                pose += s * cov * s.transpose();
            }
            c.view_mut((0, 0), (6, 6)).copy_from(&pose);
            if let Some((sens, cov)) = &moved[k] {
                let cross = sens.rows(rows.start, 6) * cov;
                c.view_mut((0, 6), (6, ni)).copy_from(&cross);
                c.view_mut((6, 0), (ni, 6)).copy_from(&cross.transpose());
            }
            c.view_mut((6, 6), (ni, ni)).copy_from(own);
            Some(c)
        })
        .collect()
}

/// A small correction of a floor pose on its floor's side (rotation vector, then translation),
/// as `odocal_calib::FloorUncertaintyMap::floor_covariance` describes it.
fn floor_correction(d: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(d[3], d[4], d[5]),
        UnitQuaternion::from_scaled_axis(Vector3::new(d[0], d[1], d[2])),
    )
}

/// The floor pose correction's components that place the floor plane (tilt about x and y,
/// height): [`floor_correction`]'s order.
const FLOOR_SHAPE: [usize; 3] = [0, 1, 5];

/// The floor pose correction's components that move the floor frame along its own plane
/// (turn about the vertical, shift along x and y): [`floor_correction`]'s order.
const FLOOR_PLACEMENT: [usize; 3] = [2, 3, 4];

/// How well the arena's floor frame is placed: the part of the first camera's floor turn
/// about the vertical and shift along the floor that moves every fix alike. None when its
/// camera file does not keep its floor's covariance.
///
/// With that turn and shift p and the rest of the floor pose and the intrinsics s (tilt,
/// height, focal length, …), p = A s + e, e independent of s: A s moves each camera's fixes
/// with the floor's plane and the lens, differently in each, and e (the conditional
/// covariance of p given s) moves them all by one turn and shift. The turn and the shift are
/// tied to the tilt (a floor seen from 2.6 m, tilted a milliradian about a point under the
/// camera, shifts its origin by the tilt times the distance), so p's own covariance
/// overstates the common move many times: 7 mm where e is 0.2 mm, on a 480x320 arena.
fn frame_placement(first: &CameraFile) -> Option<crate::FramePlacement> {
    let joint = first_floor_covariance(first)?;
    let rest_at: Vec<usize> = FLOOR_SHAPE
        .iter()
        .copied()
        .chain(6..joint.nrows())
        .collect();
    let pick = |rows: &[usize], cols: &[usize]| {
        DMatrix::from_fn(rows.len(), cols.len(), |a, b| joint[(rows[a], cols[b])])
    };
    let rest = pick(&rest_at, &rest_at);
    let cross = pick(&FLOOR_PLACEMENT, &rest_at);
    // Scaled to unit variances first: the parameters' units span many decades, and the
    // rational model's coefficients have a direction they barely tell apart.
    let scale =
        DMatrix::from_diagonal(&rest.diagonal().map(
            |v| {
                if v > 0.0 {
                    1.0 / v.sqrt()
                } else {
                    0.0
                }
            },
        ));
    let inverse = &scale * (&scale * &rest * &scale).pseudo_inverse(1e-10).ok()? * &scale;
    let e = pick(&FLOOR_PLACEMENT, &FLOOR_PLACEMENT) - &cross * inverse * cross.transpose();
    let mut covariance = [[0.0; 3]; 3];
    for (i, row) in covariance.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = 0.5 * (e[(i, j)] + e[(j, i)]);
        }
    }
    Some(crate::FramePlacement { covariance })
}

/// The first camera's joint covariance of its floor pose and intrinsics, when its camera
/// file keeps one that fits its model.
fn first_floor_covariance(file: &CameraFile) -> Option<DMatrix<f64>> {
    let c = file.floor_uncertainty.as_ref()?.floor_covariance_matrix()?;
    (c.nrows() == 6 + file.camera.parameters().len()).then_some(c)
}

/// A camera whose shared-view corners fit this many times worse than its own calibration's
/// views (and worse than [`SHARED_RESIDUAL_MIN_PX`]) is not the camera that took them: a fitted
/// arena fits them within about its calibration's RMS (1.1 times on the synthetic arena).
pub const SHARED_RESIDUAL_RATIO: f64 = 8.0;
/// Shared-view residuals below this are accepted whatever the calibration's RMS, pixels.
pub const SHARED_RESIDUAL_MIN_PX: f64 = 0.5;

/// Refuses an arena in which a camera's shared views fit far worse than its calibration: its
/// camera file belongs to another camera (files given in another order than the _cK names),
/// or a board moved between the shots. Names the worst camera.
fn check_residuals(
    cameras: &[CameraFile],
    camera_paths: &[&Path],
    rms_px: &[f64],
) -> Result<(), ArenaError> {
    let ratio = |k: usize| rms_px[k] / cameras[k].rms_px.max(1e-6);
    let bad = |k: usize| rms_px[k] > SHARED_RESIDUAL_MIN_PX && ratio(k) > SHARED_RESIDUAL_RATIO;
    let Some(worst) = (0..rms_px.len().min(cameras.len()))
        .filter(|&k| bad(k))
        .max_by(|&a, &b| ratio(a).total_cmp(&ratio(b)))
    else {
        return Ok(());
    };
    let others: Vec<String> = (0..rms_px.len().min(cameras.len()))
        .filter(|&k| k != worst && bad(k))
        .map(|k| format!("camera {k} {:.2} px", rms_px[k]))
        .collect();
    Err(ArenaError::Refused(format!(
        "camera {worst} ({}): its shared views' corners fit {:.2} px RMS against {:.3} px in its own calibration (refused above {SHARED_RESIDUAL_RATIO} times and {SHARED_RESIDUAL_MIN_PX} px{}): check that the camera files are given in the order of the _cK image names, and that the board did not move between the cameras' shots",
        camera_paths
            .get(worst)
            .map_or(String::new(), |p| p.display().to_string()),
        rms_px[worst],
        cameras[worst].rms_px,
        if others.is_empty() {
            String::new()
        } else {
            format!("; also {}", others.join(", "))
        }
    )))
}

/// A camera whose height above the floor in the arena differs from the one its own floor
/// views gave by more than this share of it sits elsewhere than its camera file's camera: the
/// two agree within 0.1 % on the synthetic arena; two files given in each other's places put
/// the cameras 3.4 % and 3.6 % off (a shared residual only 1.4 times their calibrations').
pub const HEIGHT_MISMATCH: f64 = 0.015;

/// Each camera's height above the floor: its own floor views' (none without them) and the
/// arena's.
fn heights(cameras: &[CameraFile], poses: &[FloorToCamera]) -> Vec<(Option<f64>, f64)> {
    cameras
        .iter()
        .zip(poses)
        .map(|(c, p)| {
            (
                c.floor.as_ref().map(|f| f.camera_height_m),
                p.0.inverse().translation.vector.z,
            )
        })
        .collect()
}

/// Warnings for a camera whose height in the arena is off the one its own floor views gave
/// ([`HEIGHT_MISMATCH`]): the camera file is another camera's, or the floor is not one plane.
/// Two or more such are refused: files given in each other's places (an arena written so put
/// two cameras 143 and 151 mm off, exit 0).
pub fn height_warnings(
    cameras: &[CameraFile],
    camera_paths: &[&Path],
    poses: &[FloorToCamera],
) -> Result<Vec<String>, ArenaError> {
    let off: Vec<String> = heights(cameras, poses)
        .into_iter()
        .enumerate()
        .filter_map(|(k, (own, arena))| {
            let own = own?;
            ((arena / own - 1.0).abs() > HEIGHT_MISMATCH).then(|| {
                format!(
                    "camera {k} ({}) {arena:.3} m above the floor against {own:.3} m by its own floor views",
                    camera_paths.get(k).map_or(String::new(), |p| p.display().to_string())
                )
            })
        })
        .collect();
    match off.len() {
        0 => Ok(Vec::new()),
        1 => Ok(vec![format!(
            "the shared views put {}: check that the camera file is this camera's (in the order of the _cK names), and that the floor under it is level with the shared boards",
            off[0]
        )]),
        _ => Err(ArenaError::Refused(format!(
            "the shared views put {}: camera files given in other places than their _cK names (two swapped?); nothing written: give each camera's file in its place in --camera",
            off.join(", and ")
        ))),
    }
}

/// A camera whose shared-view corners fit this many times worse than its own calibration's
/// views (below [`SHARED_RESIDUAL_RATIO`]) is warned about: a board nudged by a few
/// millimetres between the cameras' shots gives 2–5 times (the synthetic arena's cameras
/// fit theirs within 1.0–1.3 times), and its misfit is not in the fused σ.
pub const SHARED_RESIDUAL_WARN_RATIO: f64 = 3.0;

/// Warnings for cameras whose shared views fit clearly worse than their calibration, short
/// of [`check_residuals`]' refusal: the fused positions there are off by more than their σ.
pub fn shared_residual_warnings(
    cameras: &[CameraFile],
    camera_paths: &[&Path],
    rms_px: &[f64],
) -> Vec<String> {
    (0..rms_px.len().min(cameras.len()).min(camera_paths.len()))
        // A camera file without a calibration's residual (a true or hand-made one) has no
        // scale to judge by.
        .filter(|&k| {
            cameras[k].rms_px > 0.0 && rms_px[k] > SHARED_RESIDUAL_WARN_RATIO * cameras[k].rms_px
        })
        .map(|k| format!(
            "camera {k} ({}): its shared views' corners fit {:.3} px RMS, {:.1} times the {:.3} px of its own calibration: a board moved between the cameras' shots of one view, or a view is blurred; the fused σ leave that misfit out, so fixes near this camera's overlaps may be off by more than their σ (the pairs' agreement below says by how much): take the shared views again with the board left untouched between the shots",
            camera_paths[k].display(),
            rms_px[k],
            rms_px[k] / cameras[k].rms_px,
            cameras[k].rms_px
        ))
        .collect()
}

fn summarise(d: &[f64]) -> Consistency {
    let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len().max(1) as f64).sqrt();
    Consistency {
        rms_mm: rms * 1e3,
        max_mm: d.iter().copied().fold(0.0, f64::max) * 1e3,
        points: d.len(),
    }
}

/// Where two cameras saw the same corner: the distance between the floor points each camera's
/// pixel maps to, over all pairs and for each pair.
fn consistency(
    models: &[CameraModel],
    poses: &[FloorToCamera],
    observations: &[SharedObservation],
) -> Result<(Consistency, Vec<PairConsistency>), ArenaError> {
    let mut all = Vec::new();
    let mut by_pair: std::collections::BTreeMap<(usize, usize), Vec<f64>> = Default::default();
    for (i, a) in observations.iter().enumerate() {
        for b in observations[i + 1..].iter().filter(|b| b.view == a.view) {
            // The same corner in both images: by its index on the board.
            let in_b: std::collections::HashMap<u32, &Point2<f64>> =
                b.ids.iter().copied().zip(&b.corners).collect();
            for (pa, pb) in a
                .ids
                .iter()
                .zip(&a.corners)
                .filter_map(|(id, pa)| in_b.get(id).map(|pb| (pa, *pb)))
            {
                let fa = models[a.camera].pixel_to_floor(&poses[a.camera], pa, 0.0);
                let fb = models[b.camera].pixel_to_floor(&poses[b.camera], pb, 0.0);
                if let (Some(fa), Some(fb)) = (fa, fb) {
                    let d = (fa - fb).norm();
                    all.push(d);
                    by_pair
                        .entry((a.camera.min(b.camera), a.camera.max(b.camera)))
                        .or_default()
                        .push(d);
                }
            }
        }
    }
    if all.is_empty() {
        return Err(ArenaError::Input(
            "no floor point was seen by two cameras: the shared views tie nothing".into(),
        ));
    }
    Ok((
        summarise(&all),
        by_pair
            .into_iter()
            .map(|(cameras, d)| PairConsistency {
                cameras,
                consistency: summarise(&d),
            })
            .collect(),
    ))
}

/// Fits the arena ([`solve_arena`]) and assembles the arena file.
pub fn build_arena(
    cameras: &[CameraFile],
    camera_paths: &[&Path],
    shared: &[SharedView],
    board: &BoardSpec,
) -> Result<(crate::ArenaFile, ArenaSolution), ArenaError> {
    let solution = solve_arena(cameras, camera_paths, shared, board)?;
    let file = crate::ArenaFile {
        format: crate::ARENA_FORMAT.into(),
        cameras: cameras
            .iter()
            .enumerate()
            .map(|(k, c)| crate::ArenaCamera {
                source: camera_paths[k].display().to_string(),
                calibration: c.clone(),
                arena_to_camera: solution.arena_to_camera[k],
                shared_views: solution.views_per_camera[k],
                rms_px: solution.rms_px[k],
                pose_covariance: solution.pose_covariance[k]
                    .as_ref()
                    .map(|c| c.row_iter().map(|r| r.iter().copied().collect()).collect()),
            })
            .collect(),
        shared_views: shared.iter().map(|s| s.name.clone()).collect(),
        consistency: solution.consistency,
        pairs: solution.pairs.clone(),
        frame_placement: solution.frame_placement,
    };
    Ok((file, solution))
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_calib::{board_points, BoardView, FloorPlane};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const BOARD: BoardSpec = BoardSpec {
        cols: 9,
        rows: 6,
        square_m: 0.08,
        target: odocal_calib::BoardTarget::Checkerboard,
    };

    /// The three cameras' file names, as the command line would give them.
    const CAMERA_PATHS: [&str; 3] = ["a.json", "b.json", "c.json"];

    /// Three 90° cameras 2.5 m up, and boards on the floor where their views overlap; the
    /// corners are the true projections with 0.1 px of noise.
    fn scene() -> (Vec<CameraModel>, Vec<FloorToCamera>, Vec<SharedView>) {
        let cams = vec![CameraModel::from_hfov(960, 540, 90.0); 3];
        let poses: Vec<FloorToCamera> = [(0.0, 0.0, 1.0), (2.5, 0.2, -2.0), (1.2, 1.6, 3.0)]
            .iter()
            .map(|&(x, y, yaw)| {
                let above = odocal_synth::scene::ceiling_camera(2.5, 1.0, -0.5, yaw);
                FloorToCamera(above.0 * Isometry3::translation(-x, -y, 0.0))
            })
            .collect();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let object = board_points(&BOARD);
        let mut shared = Vec::new();
        for (i, &(x, y)) in [(1.0, -0.3), (1.5, 0.4), (0.4, 0.9), (1.4, 1.0), (2.0, 1.1)]
            .iter()
            .enumerate()
        {
            let board = board_on_floor(x, y, 0.3 * (i as f64 - 2.0));
            let views: Vec<(usize, BoardView)> = (0..3)
                .filter_map(|k| {
                    let corners: Vec<Point2<f64>> = object
                        .iter()
                        .filter_map(|p| cams[k].project(&(poses[k].0 * board * p)))
                        .filter(|p| p.x > 5.0 && p.y > 5.0 && p.x < 955.0 && p.y < 535.0)
                        .map(|p| {
                            p + nalgebra::Vector2::new(
                                rng.gen_range(-0.17..0.17),
                                rng.gen_range(-0.17..0.17),
                            )
                        })
                        .collect();
                    (corners.len() == object.len()).then(|| {
                        (
                            k,
                            BoardView::checkerboard(
                                format!("s{i}_c{k}.png"),
                                (960, 540),
                                corners,
                                &BOARD,
                            ),
                        )
                    })
                })
                .collect();
            if views.len() >= 2 {
                shared.push(SharedView {
                    name: format!("s{i}"),
                    views,
                });
            }
        }
        (cams, poses, shared)
    }

    fn files(cams: &[CameraModel], poses: &[FloorToCamera]) -> Vec<CameraFile> {
        cams.iter()
            .enumerate()
            .map(|(k, c)| {
                let floor = (k == 0).then(|| FloorPlane {
                    floor_to_camera: poses[0],
                    plane_rms_m: 0.0,
                    camera_height_m: 2.5,
                    views: vec![],
                });
                CameraFile::from_model(*c, floor)
            })
            .collect()
    }

    #[test]
    fn the_pose_graph_puts_every_camera_where_it_is() {
        let (cams, poses, shared) = scene();
        assert!(shared.len() >= 4, "{} shared views", shared.len());
        let paths = CAMERA_PATHS.map(Path::new);
        let sol = solve_arena(&files(&cams, &poses), &paths, &shared, &BOARD).unwrap();
        // Corner noise of 0.1 px is 0.5-0.8 mm of floor at these cameras, twice over for a pair.
        assert!(sol.consistency.rms_mm < 1.5, "{:?}", sol.consistency);
        // Each camera maps its pixels to the floor as the true camera does where the shared
        // boards tie it (a camera's far side, tied by nothing, is extrapolated).
        for k in 1..3 {
            let mut worst: f64 = 0.0;
            for px in shared
                .iter()
                .flat_map(|s| s.views.iter())
                .filter(|(c, _)| *c == k)
                .flat_map(|(_, bv)| bv.corners.iter())
            {
                let est = cams[k]
                    .pixel_to_floor(&sol.arena_to_camera[k], px, 0.0)
                    .unwrap();
                let tru = cams[k].pixel_to_floor(&poses[k], px, 0.0).unwrap();
                worst = worst.max((est - tru).norm());
            }
            // The fit averages hundreds of corners: below one corner's noise.
            assert!(worst < 1e-3, "camera {k}: {worst} m");
            assert!(sol.rms_px[k] < 0.2, "{:?}", sol.rms_px);
        }
    }

    /// Camera 1 calibrated with intrinsics off by draws from its stated covariance, camera 2
    /// almost exactly: the fitted poses make up part of camera 1's error where the boards tie
    /// it, and pass the rest on to camera 2 through the boards they share. The arena's pose
    /// covariance predicts both cameras' floor errors (camera 2's own calibration, or the
    /// corners' noise, would say nearly none: without the neighbours' part error/σ is 2.4).
    #[test]
    fn the_pose_covariance_describes_what_the_calibrations_leave() {
        let (cams, poses, shared) = scene();
        let paths = CAMERA_PATHS.map(Path::new);
        let sd = [0.8, 0.8, 0.8, 0.8, 2e-3, 1e-3, 1e-4, 1e-4, 3e-4];
        let cov = |scale: f64| -> Vec<Vec<f64>> {
            (0..sd.len())
                .map(|i| {
                    (0..sd.len())
                        .map(|j| if i == j { (scale * sd[i]).powi(2) } else { 0.0 })
                        .collect()
                })
                .collect()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (mut z2, mut count) = (0.0, 0);
        for _ in 0..12 {
            let mut f = files(&cams, &poses);
            for (file, scale) in f.iter_mut().skip(1).zip([1.0, 1e-3]) {
                let p: Vec<f64> = file
                    .camera
                    .parameters()
                    .iter()
                    .zip(&sd)
                    .map(|(v, s)| v + scale * s * (rng.gen::<f64>() - 0.5) * 12f64.sqrt())
                    .collect();
                file.camera = file.camera.with_parameters(&p);
                file.covariance = Some(cov(scale));
            }
            let (arena, _) = build_arena(&f, &paths, &shared, &BOARD).unwrap();
            for k in 1..3 {
                let cam = &arena.cameras[k];
                for px in [
                    (480.0, 270.0),
                    (150.0, 100.0),
                    (800.0, 450.0),
                    (850.0, 90.0),
                ] {
                    let px = Point2::new(px.0, px.1);
                    let est = cam
                        .calibration
                        .camera
                        .pixel_to_floor(&cam.arena_to_camera, &px, 0.0)
                        .unwrap();
                    let tru = cams[k].pixel_to_floor(&poses[k], &px, 0.0).unwrap();
                    let c = crate::track::calibration_covariance(cam, &px, 0.0).unwrap();
                    let e = est - tru;
                    z2 += e.x * e.x / c[(0, 0)] + e.y * e.y / c[(1, 1)];
                    count += 2;
                }
            }
        }
        let z_rms = (z2 / count as f64).sqrt();
        eprintln!("floor error / σ RMS {z_rms:.2} over {count} axes");
        assert!((0.5..=2.0).contains(&z_rms), "error/σ RMS {z_rms:.2}");
    }

    /// The first camera's floor (the arena's floor frame) turned about its vertical by an
    /// unknown angle turns every fix about the floor's origin: each camera's fixes are
    /// uncertain by that angle times their distance from the origin, 3 mm a milliradian at
    /// 3 m, and the arena states the turn as the frame's placement too. Tilted by an unknown
    /// angle, it moves each camera's fixes by that camera's own lines of sight, and is no
    /// placement. (Before, the arena left the first floor's uncertainty out, and fixes far
    /// from the first camera were 4.7 σ off on a small arena.)
    #[test]
    fn the_first_floors_uncertainty_reaches_every_camera() {
        let (cams, poses, shared) = scene();
        let paths = CAMERA_PATHS.map(Path::new);
        let sd_rad = 1e-3;
        let n = cams[0].parameters().len();
        // Intrinsics known all but exactly: only the first floor's pose is uncertain, by 1
        // mrad about the axis `axis`.
        let arena_with = |axis: Option<usize>| {
            let mut f = files(&cams, &poses);
            for file in &mut f {
                file.covariance = Some(
                    (0..n)
                        .map(|i| (0..n).map(|j| if i == j { 1e-18 } else { 0.0 }).collect())
                        .collect(),
                );
            }
            f[0].floor_uncertainty = axis.map(|axis| odocal_calib::FloorUncertaintyMap {
                cell_px: 960,
                cols: 1,
                rows: 1,
                sigma_mm: vec![None],
                floor_boards_px: vec![],
                model_spread_mm: vec![],
                covariance_mm2: vec![],
                floor_covariance: Some(
                    (0..6 + n)
                        .map(|i| {
                            (0..6 + n)
                                .map(|j| {
                                    if i == axis && j == axis {
                                        sd_rad * sd_rad
                                    } else {
                                        0.0
                                    }
                                })
                                .collect()
                        })
                        .collect(),
                ),
            });
            build_arena(&f, &paths, &shared, &BOARD).unwrap().0
        };
        let fix_sigma_m = |arena: &crate::ArenaFile, k: usize| {
            let cam = &arena.cameras[k];
            let px = Point2::new(480.0, 270.0);
            let at = cam
                .calibration
                .camera
                .pixel_to_floor(&cam.arena_to_camera, &px, 0.0)
                .unwrap();
            let c = crate::track::calibration_covariance(cam, &px, 0.0).unwrap();
            (c.trace().sqrt(), at)
        };
        let turned = arena_with(Some(2));
        let placement = turned.frame_placement.unwrap();
        assert!((placement.heading_sigma_rad() / sd_rad - 1.0).abs() < 1e-9);
        assert!(placement.origin_sigma_m().norm() < 1e-12);
        let tilted = arena_with(Some(0));
        assert!(tilted.frame_placement.unwrap().heading_sigma_rad() < 1e-12);
        let neither = arena_with(None);
        assert!(neither.frame_placement.is_none());
        let mut tilt_part_m = Vec::new();
        for k in 1..3 {
            let (noise_m, at) = fix_sigma_m(&neither, k);
            let part_m = |arena: &crate::ArenaFile| {
                let (sigma_m, _) = fix_sigma_m(arena, k);
                (sigma_m.powi(2) - noise_m.powi(2)).max(0.0).sqrt()
            };
            let want_m = sd_rad * at.coords.norm();
            assert!(
                (part_m(&turned) / want_m - 1.0).abs() < 0.05,
                "camera {k} at {at}: a 1 mrad turn adds {:.3} mm, its lever gives {:.3} mm",
                part_m(&turned) * 1e3,
                want_m * 1e3
            );
            // Measured: 0.33 mm at camera 1 (0.24 m from the tilt's axis), 0.73 mm at camera
            // 2 (1.64 m from it).
            let tilted_m = part_m(&tilted);
            assert!(
                tilted_m > 0.2e-3,
                "camera {k} at {at}: a 1 mrad tilt adds {:.3} mm",
                tilted_m * 1e3
            );
            tilt_part_m.push((at.y.abs(), tilted_m));
        }
        assert!(tilt_part_m[1].1 > tilt_part_m[0].1, "{tilt_part_m:?}");
    }

    /// One camera's image of one view saved under another view's name: the arena is refused
    /// (the boards' corners 10 cm and more apart), naming that image and the view it shows,
    /// since without its view the others agree within a millimetre (before: only "corners
    /// N mm apart", with advice about the camera files).
    #[test]
    fn a_misnamed_shared_image_is_named() {
        let (cams, poses, mut shared) = scene();
        let names: Vec<String> = shared.iter().map(|s| s.name.clone()).collect();
        // A view camera 1 shares with others, and another view camera 1 saw.
        let (to, from) = (0..shared.len())
            .flat_map(|a| (0..shared.len()).map(move |b| (a, b)))
            .find(|&(a, b)| {
                a != b && shared[a].views.len() == 3 && shared[b].views.iter().any(|(k, _)| *k == 1)
            })
            .expect("two views seen by camera 1, one of them by all three cameras");
        let copy = shared[from]
            .views
            .iter()
            .find(|(k, _)| *k == 1)
            .unwrap()
            .1
            .clone();
        let slot = shared[to].views.iter_mut().find(|(k, _)| *k == 1).unwrap();
        slot.1 = BoardView {
            image: format!("{}_c1.png", names[to]),
            ..copy
        };
        let paths = CAMERA_PATHS.map(Path::new);
        let e = solve_arena(&files(&cams, &poses), &paths, &shared, &BOARD)
            .unwrap_err()
            .to_string();
        let named = format!(
            "view {} ({}_c1.png shows the board where view {} has it)",
            names[to], names[to], names[from]
        );
        assert!(
            e.contains(&named)
                && e.contains("without one view the other")
                && e.contains("a misnamed, copied or swapped image"),
            "{e}"
        );
    }

    #[test]
    fn corners_numbered_the_other_way_round_are_named_or_turned_back() {
        let (cams, poses, shared) = scene();
        let paths = CAMERA_PATHS.map(Path::new);
        let refusal = |shared: &[SharedView]| {
            solve_arena(&files(&cams, &poses), &paths, shared, &BOARD)
                .unwrap_err()
                .to_string()
        };
        // One image of camera 1 numbers its board's corners from the other end (that image
        // turned 180°): its view is named.
        let mut one = shared.clone();
        let (_, bv) = one
            .iter_mut()
            .flat_map(|s| s.views.iter_mut())
            .find(|(k, _)| *k == 1)
            .unwrap();
        bv.corners.reverse();
        let e = refusal(&one);
        assert!(
            e.contains("but without one view") && e.contains("turned alike"),
            "{e}"
        );
        // Every image of camera 1 does (a camera mounted turned 180° from the first): that
        // camera's numbering is turned back, and the arena is the one its true numbering gives.
        let mut all = shared.clone();
        for (_, bv) in all
            .iter_mut()
            .flat_map(|s| s.views.iter_mut())
            .filter(|(k, _)| *k == 1)
        {
            bv.corners.reverse();
        }
        let fs = files(&cams, &poses);
        let right = solve_arena(&fs, &paths, &shared, &BOARD).unwrap();
        let turned = solve_arena(&fs, &paths, &all, &BOARD).unwrap();
        assert_eq!(right.renumbered, None);
        let renumbered = turned.renumbered.clone().unwrap();
        assert_eq!(renumbered.cameras, vec![1]);
        assert!(
            renumbered.numbered_as_recorded_mm > REFUSE_RMS_MM,
            "{renumbered:?}"
        );
        for k in 0..3 {
            let apart_m = (turned.arena_to_camera[k].0.inverse().translation.vector
                - right.arena_to_camera[k].0.inverse().translation.vector)
                .norm();
            assert!(apart_m < 1e-6, "camera {k} {apart_m} m from its place");
        }
        assert!(
            (turned.consistency.rms_mm - right.consistency.rms_mm).abs() < 1e-6,
            "{} vs {} mm",
            turned.consistency.rms_mm,
            right.consistency.rms_mm
        );
        // Cameras 1 and 2 both mounted turned from the first: both are read back.
        let mut two = shared.clone();
        for (_, bv) in two
            .iter_mut()
            .flat_map(|s| s.views.iter_mut())
            .filter(|(k, _)| *k != 0)
        {
            bv.corners.reverse();
        }
        let turned = solve_arena(&fs, &paths, &two, &BOARD).unwrap();
        assert_eq!(turned.renumbered.map(|r| r.cameras), Some(vec![1, 2]));
        for k in 0..3 {
            let apart_m = (turned.arena_to_camera[k].0.inverse().translation.vector
                - right.arena_to_camera[k].0.inverse().translation.vector)
                .norm();
            assert!(apart_m < 1e-6, "camera {k} {apart_m} m from its place");
        }
    }
}
