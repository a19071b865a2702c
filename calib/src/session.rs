//! A calibration session: the board found in every image, views sorted into used and
//! skipped, one camera and resolution checked, Zhang's calibration, the floor plane from the
//! floor views, and the summary `odocal calibrate` prints.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::detect::guess_board_size;
use crate::floor::FloorBoards;
use crate::{
    calibrate, compare_models, detect_file, ArucoDictionary, BoardSpec, BoardTarget, BoardView,
    CalibError, CameraFile, Detection, FloorUncertaintyMap, LensModel, SkippedView, UncertaintyMap,
    CAMERA_FORMAT,
};

/// Inner corners a side of the largest checkerboard read: a 50x50 board of 2 cm squares is
/// a metre across.
const MAX_BOARD_CORNERS: u32 = 50;

impl BoardSpec {
    /// Parses `--board COLSxROWS` (inner corners) with the square side in metres.
    pub fn parse(s: &str, square_m: f64) -> Result<Self, CalibError> {
        let bad = |why: String| CalibError::Input(format!("--board {s:?}: {why}"));
        let (c, r) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| bad("expected COLSxROWS of inner corners, e.g. 9x6".into()))?;
        let cols: u32 = c
            .trim()
            .parse()
            .map_err(|_| bad(format!("{c:?} is not a number")))?;
        let rows: u32 = r
            .trim()
            .parse()
            .map_err(|_| bad(format!("{r:?} is not a number")))?;
        if cols < 3 || rows < 3 {
            return Err(bad("need at least 3x3 inner corners".into()));
        }
        // Looking for a board of thousands of corners takes OpenCV minutes to fail.
        if cols > MAX_BOARD_CORNERS || rows > MAX_BOARD_CORNERS {
            return Err(bad(format!(
                "at most {MAX_BOARD_CORNERS} inner corners a side (one fewer than the squares): count the board's inner corners"
            )));
        }
        check_square(square_m, "0.03 for 3 cm")?;
        Ok(BoardSpec::checkerboard(cols, rows, square_m))
    }

    /// Parses a ChArUco board: `--board COLSxROWS` in squares (as OpenCV counts them), the
    /// square and marker sides in metres and the dictionary's name (`4X4_50`, ...).
    pub fn parse_charuco(
        s: &str,
        square_m: f64,
        marker_m: f64,
        dictionary: &str,
    ) -> Result<Self, CalibError> {
        let bad = |why: String| CalibError::Input(format!("--board {s:?}: {why}"));
        let (c, r) = s.split_once(['x', 'X']).ok_or_else(|| {
            bad("expected COLSxROWS of squares for a ChArUco board, e.g. 11x8".into())
        })?;
        let cols: u32 = c
            .trim()
            .parse()
            .map_err(|_| bad(format!("{c:?} is not a number")))?;
        let rows: u32 = r
            .trim()
            .parse()
            .map_err(|_| bad(format!("{r:?} is not a number")))?;
        if cols < 3 || rows < 3 {
            return Err(bad(
                "a ChArUco board needs at least 3x3 squares (--board counts squares for ChArUco)"
                    .into(),
            ));
        }
        check_square(square_m, "0.04 for 4 cm")?;
        let dictionary = ArucoDictionary::from_name(dictionary).ok_or_else(|| {
            CalibError::Input(format!(
                "--dictionary {dictionary:?}: not an ArUco dictionary OpenCV knows; one of {}",
                ArucoDictionary::names()
            ))
        })?;
        let board = BoardSpec {
            cols: cols - 1,
            rows: rows - 1,
            square_m,
            target: BoardTarget::Charuco {
                marker_m,
                dictionary,
            },
        };
        crate::charuco::check_board(&board)?;
        Ok(board)
    }
}

/// The sides a board's printed squares can have, metres: under 2 mm no camera over a floor
/// resolves them, and a value there is a size given in other units (`--square 1e-6` put the
/// camera 0.00 m above the floor, exit 0).
const SQUARE_M: std::ops::Range<f64> = 0.002..1.0;

/// Refuses a square side outside [`SQUARE_M`], with an example in metres.
fn check_square(square_m: f64, example: &str) -> Result<(), CalibError> {
    if square_m.is_finite() && SQUARE_M.contains(&square_m) {
        return Ok(());
    }
    Err(CalibError::Input(format!(
        "--square {square_m}: the square size is in metres, e.g. {example}; a printed board's squares are {} mm to {} m",
        SQUARE_M.start * 1000.0,
        SQUARE_M.end
    )))
}

/// A calibrated camera and the views it skipped, as notes for the user.
pub struct Session {
    /// camera.json's content.
    pub file: CameraFile,
    /// What the user should know, each line starting "note:" or "warning:" (\"note: skipped
    /// IMAGE: reason\" for every image without the board).
    pub notes: Vec<String>,
}

/// Which lens model to calibrate: one named, or the best by held-out error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelChoice {
    /// Fit every model and keep the one that predicts held-out views best ([`compare_models`]).
    Auto,
    /// This model.
    Fixed(LensModel),
}

impl ModelChoice {
    /// Parses `--model pinhole5|rational|fisheye|auto`.
    pub fn parse(s: &str) -> Result<Self, CalibError> {
        if s == "auto" {
            return Ok(ModelChoice::Auto);
        }
        LensModel::parse(s).map(ModelChoice::Fixed).ok_or_else(|| {
            CalibError::Input(format!(
                "--model {s:?} is not a lens model: use pinhole5 (OpenCV's default k1 k2 p1 p2 k3), rational (wide lenses to ~120°), fisheye (Kannala–Brandt, to ~180°) or auto (pick by held-out error)"
            ))
        })
    }
}

/// The largest angle between a ceiling camera's axis and straight down that passes unwarned,
/// degrees.
const MAX_CEILING_TILT_DEG: f64 = 30.0;

/// Heights above the floor a ceiling camera over small robots can plausibly have, metres;
/// outside them the board's square size is more likely wrong than the camera.
pub(crate) const CEILING_HEIGHT_M: std::ops::RangeInclusive<f64> = 0.5..=10.0;

/// Sharp views of a flat board through one camera fit within this RMS, pixels (OpenCV's
/// sample photographs: 0.25 px; odocal's synthetic views: 0.05 px).
const LARGE_RMS_PX: f64 = 1.0;

/// How much worse views left out of the calibration may be predicted than the views fit,
/// as a ratio of RMS errors, with `n` views: the intrinsics fitted without a view are a
/// little less certain, more so with few views (measured: up to 1.25 with 4 views, 1.04 with
/// 6 to 10, 1.04 with 20, 1.02 on OpenCV's 13 sample photographs).
fn held_out_tolerance(n: usize) -> f64 {
    1.1 + 1.0 / n.max(1) as f64
}

/// Another lens model's calibration of the same views judged on them: the model, its fit RMS
/// and its held-out RMS, pixels.
type Alternative = (LensModel, f64, f64);

/// What the views left out of the calibration say: nothing when they are predicted about as
/// well as the views fit. Otherwise the blame goes, in turn, to the few views predicted far
/// worse than the median view (each reaches where no other does and is extrapolated to when
/// left out, or came from another camera); to the lens model when another model predicts
/// them within its own fit (the views then agree on one camera); else to the views (two
/// cameras, a zoom or focus changed between views, a board that is not flat). `unlocated`
/// views could not be located with the calibration of the others at all; `alternatives` is
/// called only when there is something to blame.
fn consistency_notes(
    model: LensModel,
    rms_px: f64,
    views: &[crate::ViewResidual],
    unlocated: usize,
    alternatives: &dyn Fn() -> Vec<Alternative>,
) -> Vec<String> {
    let tolerance = held_out_tolerance(views.len());
    let held_rms = held_out_rms_px(views);
    let ratio = held_rms.map(|h| h / rms_px.max(1e-9));
    let disagree = unlocated > 0 || ratio.is_some_and(|r| r > tolerance);
    if rms_px <= LARGE_RMS_PX && !disagree {
        return vec![];
    }
    let worst = worst_views(views, 3);
    let what = match (held_rms, ratio) {
        _ if unlocated > 0 => format!(
            "{unlocated} of the {} views could not be located at all with the {model} calibration of the other views",
            views.len()
        ),
        (Some(h), Some(r)) if disagree => format!(
            "a view left out of the calibration is predicted {:.0} % worse than the views fit (held-out RMS {h:.3} px against {rms_px:.3} px; views of one camera agree within {:.0} % with {} views)",
            (r - 1.0) * 100.0,
            (tolerance - 1.0) * 100.0,
            views.len()
        ),
        _ => format!(
            "the RMS reprojection error is {rms_px:.3} px, where sharp views of a flat board fit within {LARGE_RMS_PX} px"
        ),
    };
    if disagree {
        // The median view predicted as well as the views fit: a few views far out, not the
        // model (the median is what chose it) nor the camera.
        let held: Vec<f64> = views.iter().filter_map(|v| v.held_out_rms_px).collect();
        let median_px = crate::select::median(&held);
        let n_far = views
            .iter()
            .filter(|v| v.held_out_rms_px.is_some_and(|h| h > tolerance * rms_px))
            .count();
        // A few: at most a third of the views (3 of 10 for a 110° lens whose views reach its
        // corners one by one). Two cameras' views mixed half and half leave the median view
        // predicted well by a model wide enough to fit both (a fisheye over a 70° and a 110°
        // camera, 0.5 px), with 7 of 16 views far out.
        if unlocated == 0 && median_px <= tolerance * rms_px && 3 * n_far <= views.len() {
            return vec![format!(
                "warning: {n_far} view(s) left out of the calibration are predicted far worse than the median view ({} against {median_px:.3} px; the views fit to {rms_px:.3} px): each reaches a part of the image no other view covers, where the {model} model is extrapolated when it is left out and rests on it alone when it is in, unless it was taken by another camera or at another zoom; add views with the board over the same part of the image",
                worst_views(views, n_far.clamp(1, 3)).join(", ")
            )];
        }
        let fine = alternatives()
            .into_iter()
            .filter(|(m, fit, held)| *m != model && *held <= tolerance * fit)
            .min_by(|a, b| a.2.total_cmp(&b.2));
        if let Some((other, fit, held)) = fine {
            return vec![format!(
                "warning: the {model} lens model does not predict these views: {what}; yet the {other} model predicts every view left out of its calibration within its fit (held-out RMS {held:.3} px against {fit:.3} px), so the views agree on one camera and the {model} model is what misfits it: calibrate with --model {other}. Worst views: {}",
                worst.join(", ")
            )];
        }
    }
    vec![format!(
        "warning: the views do not fit one camera: {what}. Were all views taken by this camera at the same zoom and focus, with the board flat and sharp? Worst views: {}",
        worst.join(", ")
    )]
}

/// Most calibrations the view-agreement check runs: views beyond this many are left out
/// in folds.
const VIEW_CHECK_FOLDS: usize = 10;

/// A warning naming the views whose own focal length or principal point disagrees with the
/// calibration of the other views beyond chance ([`crate::view_consistency`]): a varifocal
/// lens nudged between photos (5 %) or photos turned 180° put fx 11σ and cx 4σ off while the
/// held-out error stayed within 7 % of the fit, below what the held-out check can tell.
fn disagreeing_views_note(
    cal: &crate::Calibration,
    views: &[BoardView],
    board: &BoardSpec,
    model: LensModel,
) -> Option<String> {
    // Each view is judged against a calibration without it. Up to ten views each have their
    // own; beyond, views are left out ten folds at a time (20 views: 10 calibrations of 18,
    // not 20 of 19), which keeps nine tenths of the views in each calibration at half the cost.
    let folds = views.len().min(VIEW_CHECK_FOLDS);
    let per_fold: Vec<Vec<crate::view_consistency::ViewIntrinsics>> = (0..folds)
        .into_par_iter()
        .map(|fold| {
            let others: Vec<BoardView> = views
                .iter()
                .enumerate()
                .filter(|(k, _)| k % folds != fold)
                .map(|(_, v)| v.clone())
                .collect();
            let Ok(c) = calibrate(&others, board, model) else {
                return Vec::new();
            };
            views
                .iter()
                .enumerate()
                .filter(|(k, _)| k % folds == fold)
                .filter_map(|(_, v)| {
                    let pose = crate::solve_pnp(
                        &c.camera,
                        &v.object_points,
                        &v.corners,
                        opencv::calib3d::SOLVEPNP_ITERATIVE,
                    )
                    .ok()??;
                    let o = crate::Observation {
                        pose: crate::BoardToCamera(pose),
                        object: &v.object_points,
                        image: &v.corners,
                    };
                    crate::view_consistency::view_intrinsics(
                        &c.camera,
                        &c.covariance,
                        c.rms_px * c.rms_px / 2.0,
                        std::slice::from_ref(&v.image),
                        std::slice::from_ref(&o),
                    )
                    .pop()
                })
                .collect()
        })
        .collect();
    let per_view: Vec<crate::view_consistency::ViewIntrinsics> =
        per_fold.into_iter().flatten().collect();
    if !crate::view_consistency::disagree(&per_view) {
        return None;
    }
    let mut worst: Vec<&crate::view_consistency::ViewIntrinsics> = per_view.iter().collect();
    worst.sort_by(|a, b| b.chi2.total_cmp(&a.chi2));
    let named: Vec<String> = worst
        .iter()
        .filter(|v| v.chi2 > crate::view_consistency::VIEW_CHI2)
        .take(6)
        .chain(worst.first().filter(|v| v.chi2 <= crate::view_consistency::VIEW_CHI2))
        .map(|v| {
            format!(
                "{} (focal length {:+.1} % ± {:.1}, principal point {:+.1} ± {:.1}, {:+.1} ± {:.1} px; χ² {:.0})",
                name_among(&cal.views, &v.image),
                v.focal_share * 100.0,
                v.sigma[0] * 100.0,
                v.dcx_px,
                v.sigma[1],
                v.dcy_px,
                v.sigma[2],
                v.chi2
            )
        })
        .collect();
    let n = per_view.len();
    let sum: f64 = per_view.iter().map(|v| v.chi2).sum();
    Some(format!(
        "warning: the views do not agree on one camera, though together they fit one: each view's own focal length and principal point, fitted against the calibration of the other views, differ from it by χ² {sum:.0} summed over the {n} views, where one camera's views sum to about {} ± {:.0}; the ± below do not cover the difference, and fx, cx, cy may be off by many σ. Most disagreeing: {}. Were some photos taken at another zoom or focus, turned 180° or mirrored by a photo viewer (which moves the principal point to the other side), or by another camera? Leave those views out",
        3 * n,
        (6.0 * n as f64).sqrt(),
        named.join("; ")
    ))
}

/// A warning when another lens model fits all the views clearly better than the chosen one
/// ([`crate::select::CLEARLY_BETTER_FIT`]) but predicts the median held-out view worse.
fn misfit_note(chosen: &crate::ModelScore, scores: &[crate::ModelScore]) -> Option<String> {
    let fit = chosen.fit_rms_px?;
    let better = scores
        .iter()
        .filter(|s| s.fits_clearly_better_than(fit))
        .min_by(|a, b| {
            a.fit_rms_px
                .unwrap_or(fit)
                .total_cmp(&b.fit_rms_px.unwrap_or(fit))
        })?;
    Some(format!(
        "warning: the {} model chosen fits the views {:.0} % worse than the {} model (RMS {fit:.3} px against {:.3} px), more than the {} model's extra parameters explain: it misfits the lens, and the ± below do not cover that misfit; the floor is vouched for only where the two models agree. More views reaching the image's corners and edges tell the models apart",
        chosen.model,
        (fit / better.fit_rms_px.unwrap_or(fit) - 1.0) * 100.0,
        better.model,
        better.fit_rms_px.unwrap_or(fit),
        better.model,
    ))
}

/// A model the user fixed that fits the views this many times worse than another is refused:
/// nearly all its residual is its misfit (a 150° fisheye as `pinhole5`: 12 times at 640x360,
/// where it stays under a pixel, 24 times at 1280x720), which the floor views would otherwise
/// take the blame for, or a camera file be written off by 17σ.
const GROSS_MISFIT: f64 = 3.0;

/// The other lens models' calibrations of the views, for the checks of a model the user fixed:
/// the one written stays the user's.
fn other_models(
    views: &[BoardView],
    board: &BoardSpec,
    chosen: LensModel,
) -> Vec<(LensModel, crate::Calibration)> {
    LensModel::ALL
        .into_iter()
        .filter(|m| *m != chosen)
        .filter_map(|m| calibrate(views, board, m).ok().map(|c| (m, c)))
        .collect()
}

/// Judges the lens model the user chose against the others' fits (`others`: model and RMS,
/// pixels) by the rules `--model auto` uses: refused when another fits the views
/// [`GROSS_MISFIT`] times better (a fisheye or wide lens calibrated as `pinhole5`, the model
/// OpenCV's examples use, would otherwise be blamed on the views or the floor boards, which
/// then disagree by degrees); a warning naming the better model when it fits clearly better
/// ([`crate::select::CLEARLY_BETTER_FIT`]), as the ± do not cover the misfit.
fn judge_fixed_model(
    chosen: LensModel,
    rms_px: f64,
    others: &[(LensModel, f64)],
) -> Result<Option<String>, CalibError> {
    let Some(&(other, other_px)) = others.iter().min_by(|a, b| a.1.total_cmp(&b.1)) else {
        return Ok(None);
    };
    let (chosen, other) = (chosen.name(), other.name());
    if other_px <= LARGE_RMS_PX && other_px * GROSS_MISFIT < rms_px {
        return Err(CalibError::Input(format!(
            "--model {chosen} does not fit these views (RMS reprojection error {rms_px:.3} px), but the {other} model fits them to {other_px:.3} px, {:.0} times better: the lens is wider or more distorted than {chosen} describes; calibrate with --model {other}, or leave --model out (auto picks the model by held-out error)",
            rms_px / other_px
        )));
    }
    if other_px * (1.0 + crate::select::CLEARLY_BETTER_FIT) < rms_px {
        return Ok(Some(format!(
            "warning: --model {chosen} fits the views {:.0} % worse than the {other} model (RMS {rms_px:.3} px against {other_px:.3} px), more than the {other} model's extra parameters explain: it misfits the lens, and the ± below do not cover that misfit; the floor is vouched for only where the two models agree. Calibrate with --model {other}",
            (rms_px / other_px - 1.0) * 100.0
        )));
    }
    Ok(None)
}

/// The RMS over the views of their held-out errors, pixels (None when none was measured).
fn held_out_rms_px(views: &[crate::ViewResidual]) -> Option<f64> {
    let held: Vec<f64> = views.iter().filter_map(|v| v.held_out_rms_px).collect();
    (!held.is_empty()).then(|| (held.iter().map(|e| e * e).sum::<f64>() / held.len() as f64).sqrt())
}

/// The `n` views worst predicted when left out (by their fit error when no held-out error
/// was measured), each as "image error px".
fn worst_views(views: &[crate::ViewResidual], n: usize) -> Vec<String> {
    let error = |v: &crate::ViewResidual| v.held_out_rms_px.unwrap_or(v.rms_px);
    let mut worst: Vec<&crate::ViewResidual> = views.iter().collect();
    worst.sort_by(|a, b| error(b).total_cmp(&error(a)));
    worst
        .iter()
        .take(n)
        .map(|v| format!("{} {:.3} px", name_among(views, &v.image), error(v)))
        .collect()
}

/// The fewest views `--model auto` can judge lens models on: each is left out in turn and
/// located with the calibration of the others, which Zhang's method needs 3 for.
pub const AUTO_MIN_VIEWS: usize = 4;

/// `choice`, or pinhole5 with a warning in `notes` when `--model auto` has too few views
/// (`n_views`) to judge lens models on: 3 views calibrate (README), so refusing them for
/// want of a judgement would stop a user whom OpenCV's default model serves; the two model
/// steps auto would have taken are counted on `on_step`.
fn auto_or_pinhole5(
    choice: ModelChoice,
    n_views: usize,
    notes: &mut Vec<String>,
    on_step: &(dyn Fn() + Sync),
) -> ModelChoice {
    if choice != ModelChoice::Auto || n_views >= AUTO_MIN_VIEWS {
        return choice;
    }
    notes.push(format!(
        "warning: --model auto judges lens models on views left out of the calibration, which needs at least {AUTO_MIN_VIEWS} views, and there are {n_views}: pinhole5 (OpenCV's default model) is calibrated unjudged; add views for the model to be chosen, or give --model fisheye or --model rational for a wide lens"
    ));
    on_step();
    on_step();
    ModelChoice::Fixed(LensModel::Pinhole5)
}

/// Calibrates from `images` and, when given, fixes the floor from `floor` images;
/// `on_image` is called after each image's detection and after each model's cross-validation
/// (for a progress bar: images + 3 steps with `--model auto`, images + 1 otherwise). The
/// floor board is `board`, or `board` with the square side `floor_square_m` (metres) when
/// given: one flat board seen alone cannot tell its own scale, so a floor board of another
/// size than the hand-held one must be given, or every floor distance and the camera's height
/// come out scaled by the ratio of the two squares. A ChArUco floor board's markers are taken
/// as scaled alike.
pub fn calibrate_session(
    images: &[PathBuf],
    floor: &[PathBuf],
    board: &BoardSpec,
    floor_square_m: Option<f64>,
    choice: ModelChoice,
    on_image: &(dyn Fn() + Sync),
) -> Result<Session, CalibError> {
    let floor_board = match floor_square_m {
        None => *board,
        Some(sq) => {
            check_square(sq, "0.08 for 8 cm").map_err(|e| {
                CalibError::Input(e.to_string().replacen("--square", "--floor-square", 1))
            })?;
            let mut b = *board;
            b.square_m = sq;
            if let BoardTarget::Charuco {
                marker_m,
                dictionary,
            } = board.target
            {
                b.target = BoardTarget::Charuco {
                    marker_m: marker_m * sq / board.square_m,
                    dictionary,
                };
            }
            b
        }
    };
    let square_option = if floor_square_m.is_some() {
        "--floor-square"
    } else {
        "--square"
    };
    if images.is_empty() {
        return Err(CalibError::Input(if floor.is_empty() {
            "no images: give the checkerboard views to calibrate from".into()
        } else {
            format!(
                "no calibration views: --floor took all {} files after it as floor images; put the views before --floor, or --floor last",
                floor.len()
            )
        }));
    }
    // A ChArUco board taken for a checkerboard is named from its markers in the first view:
    // OpenCV's checkerboard search fails on it slowly (80 s a 1280x720 view), so the hint
    // used to come after minutes.
    let markers = crate::charuco::markers_seen(&images[0]);
    if let (Some((d, n)), false) = (markers, board.is_charuco()) {
        return Err(CalibError::Input(format!(
            "{} shows a ChArUco board ({n} markers of dictionary {d}), not a plain checkerboard: pass --target charuco --dictionary {d}, with --board counting its squares and --marker the side of a marker",
            images[0].display()
        )));
    }
    // A ChArUco board's squares are a checkerboard too: its markers are named below instead.
    let quick = if markers.is_none() {
        crate::detect::quick_board_size_check(&images[0], board)
    } else {
        None
    };
    if let Some(seen) = quick {
        return Err(CalibError::Input(seen.refusal(&images[0], board)));
    }
    // The floor images' sizes are read from their headers up front: a floor view turned 90°
    // was refused only after every view had been calibrated.
    let header_sizes: Sizes = images[..1]
        .iter()
        .chain(floor)
        .filter_map(|p| {
            image::image_dimensions(p)
                .ok()
                .map(|s| (p.display().to_string(), s))
        })
        .collect();
    if header_sizes.len() == floor.len() + 1 {
        check_sizes(&header_sizes)?;
    }
    let detections = detect_all(images, board, on_image)?;
    let (views, mut skipped, sizes) = split(detections);
    check_sizes(&sizes)?;
    let n_found = views.len();
    let views = distinct_views(views, &mut skipped);
    if views.len() < n_found && views.len() < 3 {
        return Err(CalibError::Input(format!(
            "only {} distinct view(s): {} of the {n_found} images with the board repeat another view ({}); Zhang calibration needs at least 3 views of the board at different tilts",
            views.len(),
            n_found - views.len(),
            skipped
                .iter()
                .find(|s| s.reason.starts_with("the same view"))
                .map_or(String::new(), |s| format!("{}: {}", s.image, s.reason))
        )));
    }
    check_board_size(&views, board)?;
    let legacy_layout = check_layouts(views.iter())?;
    let mut notes: Vec<String> = skipped
        .iter()
        .map(|s| format!("note: skipped {}: {}", s.image, s.reason))
        .collect();
    notes.extend(crate::detect::display_rotation_note(
        images.iter().chain(floor).map(PathBuf::as_path),
    ));
    if views.is_empty() {
        // Blank frames are named as such, not as a wrong --board.
        if let (Some(first), true) = (
            skipped.first(),
            skipped
                .iter()
                .all(|s| s.reason.starts_with("the image is uniform")),
        ) {
            return Err(CalibError::Input(format!(
                "{}: {}; none of the {} calibration image(s) shows anything (check the camera's exposure and how the frames were saved)",
                first.image,
                first.reason,
                images.len()
            )));
        }
        return Err(no_board_error(images, board, "calibration"));
    }
    if legacy_layout {
        notes.push(format!(
            "note: the ChArUco board is in the layout OpenCV drew before 4.6 (its top-left square white, holding marker 0; OpenCV 4.6 on makes it black for an even number of rows): its corners are read as on that board, corner 0 and the floor frame's axes where the printed board has them ({})",
            views[0].image
        ));
    }
    let choice = auto_or_pinhole5(choice, views.len(), &mut notes, on_image);
    // Another lens model fitting the views clearly better: the floor views, located through
    // the same misfit, are not to take the blame for it.
    let mut model_misfit: Option<String> = None;
    let (model, model_comparison, held_out) = match choice {
        ModelChoice::Auto => {
            let scores = compare_models(&views, board, &|_| on_image())?;
            let chosen = scores
                .iter()
                .find(|s| s.chosen)
                .ok_or_else(|| CalibError::Input("no lens model fits these views".into()))?;
            let held = chosen.view_held_out_rms_px.clone();
            model_misfit = misfit_note(chosen, &scores);
            notes.extend(model_misfit.clone());
            (chosen.model, scores, held)
        }
        ModelChoice::Fixed(m) => {
            // The held-out error is a judgement, not a requirement: with too few views for
            // folds the calibration stands without it.
            let held = if views.len() >= 4 {
                match crate::select::held_out_errors(&views, board, m) {
                    Ok(h) => h,
                    Err(e) => {
                        notes.push(format!(
                            "warning: no held-out error: calibrating without some of the views failed ({e}); the fit below may rest on a few decisive views"
                        ));
                        vec![]
                    }
                }
            } else {
                vec![]
            };
            on_image();
            (m, vec![], held)
        }
    };
    let mut cal = calibrate(&views, board, model)?;
    check_one_camera(&views, board, model, cal.camera.intrinsics.fx)?;
    // With the model fixed, the others fitting clearly better bound the vouched floor as they
    // do when auto chooses.
    let mut fitting_better: Vec<crate::CameraModel> = vec![];
    if let ModelChoice::Fixed(m) = choice {
        let others = other_models(&views, board, m);
        let fits: Vec<(LensModel, f64)> = others.iter().map(|(m, c)| (*m, c.rms_px)).collect();
        model_misfit = judge_fixed_model(m, cal.rms_px, &fits)?;
        notes.extend(model_misfit.clone());
        fitting_better = others
            .into_iter()
            .filter(|(_, c)| c.rms_px * (1.0 + crate::select::CLEARLY_BETTER_FIT) < cal.rms_px)
            .map(|(_, c)| c.camera)
            .collect();
    }
    // A view that did not project has no error to print: it is counted instead.
    for (v, h) in cal.views.iter_mut().zip(&held_out) {
        v.held_out_rms_px = h.is_finite().then_some(*h);
    }
    let unlocated = held_out.iter().filter(|h| !h.is_finite()).count();
    notes.extend(crate::coverage::coverage_notes(&cal.camera, &views));
    notes.extend(disagreeing_views_note(&cal, &views, board, model));
    let alternatives = || -> Vec<Alternative> {
        if !model_comparison.is_empty() {
            return model_comparison
                .iter()
                .filter_map(|s| Some((s.model, s.fit_rms_px?, s.held_out_rms_px?)))
                .collect();
        }
        LensModel::ALL
            .into_iter()
            .filter(|m| *m != model)
            .filter_map(|m| {
                let fit = calibrate(&views, board, m).ok()?.rms_px;
                let held = crate::select::held_out_errors(&views, board, m).ok()?;
                held.iter()
                    .all(|h| h.is_finite())
                    .then(|| (m, fit, crate::select::rms(&held)))
            })
            .collect()
    };
    notes.extend(consistency_notes(
        model,
        cal.rms_px,
        &cal.views,
        unlocated,
        &alternatives,
    ));
    let mut floor_uncertainty = None;
    let floor = if floor.is_empty() {
        None
    } else {
        let fd = detect_all(floor, &floor_board, on_image)?;
        // The first floor view fixes the floor frame (README, ARCHITECTURE): without its board
        // the next view's would, and every trajectory would come out moved and turned.
        if let (Some(Detection::NotFound { image, reason, .. }), true) = (fd.first(), fd.len() > 1)
        {
            // Markers too small to read are a matter of pixels, which the advice then gives.
            return Err(CalibError::Input(if reason.contains("too few pixels") {
                format!(
                    "the first floor view {image}, which fixes the floor frame's origin and axes: {reason}"
                )
            } else {
                format!(
                    "the first floor view {image} fixes the floor frame's origin and axes, but {reason} there: the next view's board would fix them instead, elsewhere; retake that view with the whole board in sight, or give first the floor view whose board should be the origin"
                )
            }));
        }
        let (fviews, mut fskipped, fsizes) = split(fd);
        // A floor photo given twice would count its board twice in the joint floor fit and
        // halve the floor's σ with no new information.
        let fviews = distinct_views(fviews, &mut fskipped);
        check_board_size(&fviews, &floor_board)?;
        let fviews = odd_layout_floor_view(fviews, legacy_layout, &mut fskipped)?;
        check_layouts(views.iter().chain(&fviews))?;
        // The hand-held views read the board with these very options: a floor view's markers
        // out of place are unreadable ones (small or blurred), not wrong options.
        if floor_square_m.is_none() {
            for s in &mut fskipped {
                if let Some(at) = s
                    .reason
                    .find(": check --board (squares), --square and --marker")
                {
                    s.reason.truncate(at);
                    s.reason.push_str(": unreadable, the markers too small or blurred to read reliably (the hand-held views read the board with these options)");
                }
            }
        }
        check_sizes(&[sizes[..1].to_vec(), fsizes].concat())?;
        notes.extend(
            fskipped
                .iter()
                .map(|s| format!("note: skipped floor view {}: {}", s.image, s.reason)),
        );
        if fviews.is_empty() {
            return Err(no_board_error(floor, &floor_board, "floor"));
        }
        // The corners' noise per coordinate: the calibration's RMS is per corner (2-D).
        let corner_sigma_px = cal.rms_px / std::f64::consts::SQRT_2;
        let boards = FloorBoards::locate(&cal.camera, &fviews, &floor_board, corner_sigma_px)?;
        let fitted = boards.fit_parameters(&cal.camera);
        let plane = boards.plane(&fitted);
        let fits_camera = crate::floor_consistency::check_floor_fits_camera(
            &cal.camera,
            &cal.covariance,
            &boards,
            &fitted,
            &plane,
            cal.rms_px,
        );
        // The lens model's misfit is named first: through a model that misfits the lens, the
        // floor boards held on one plane misfit too (pinhole5 on a rational lens: "another
        // zoom or focus?", where without floor views the model was rightly named).
        let fits_camera = match (fits_camera, &model_misfit) {
            (Err(e), Some(m)) => {
                let m = m.trim_start_matches("warning: ");
                let head = m.split(", more than").next().unwrap_or(m);
                let advice = m.rsplit(". ").next().unwrap_or_default();
                return Err(CalibError::Input(format!(
                    "{head}, more than its extra parameters explain: the {model} model misfits the lens, and through that misfit the floor views do not fit the camera either, the model's doing rather than theirs; {advice} (the floor check said: {e})"
                )));
            }
            (r, _) => r?,
        };
        notes.extend(fits_camera);
        if !CEILING_HEIGHT_M.contains(&plane.camera_height_m) {
            let high = plane.camera_height_m > *CEILING_HEIGHT_M.end();
            notes.push(format!(
                "warning: by these floor boards the camera is {:.2} m above the floor, outside the {:.1}–{:.0} m of a ceiling camera over small robots; is {square_option} {} the side of one square in metres? (a square 10 times too {} makes every floor distance 10 times too {})",
                plane.camera_height_m,
                CEILING_HEIGHT_M.start(),
                CEILING_HEIGHT_M.end(),
                floor_board.square_m,
                if high { "large" } else { "small" },
                if high { "large" } else { "small" },
            ));
        }
        // A ceiling camera looks nearly straight down; a floor 30° or more off its axis is a
        // camera on a wall, or a floor view of a board that was not lying on the floor.
        let up_in_camera = plane.floor_to_camera.0.rotation * nalgebra::Vector3::z();
        let tilt_deg = up_in_camera.z.abs().min(1.0).acos().to_degrees();
        if tilt_deg > MAX_CEILING_TILT_DEG {
            notes.push(format!(
                "warning: by the floor views the camera looks {tilt_deg:.0}° away from straight down (a ceiling camera looks within {MAX_CEILING_TILT_DEG:.0}° of it){}: if it hangs level, {} not lying flat on the floor (held by hand, or a calibration view given as a floor view), and every floor position is wrong by up to metres; give --floor only photographs of a board lying on the floor",
                if fviews.len() == 1 { ", and one board alone sets the floor" } else { "" },
                if fviews.len() == 1 { "the floor board was" } else { "the floor boards were" }
            ));
        }
        notes.extend(turned_floor_note(&fviews[0], &floor_board));
        notes.extend(views_beyond_floor_note(
            &cal.poses,
            &views,
            &plane,
            square_option,
            floor_board.square_m,
        ));
        if let [only] = fviews.as_slice() {
            notes.push(format!(
                "warning: the floor rests on one board ({}): nothing checks that it lies flat on the floor, and its tilt alone sets the floor's; lay the board at 3 or more places spread over the floor",
                only.image
            ));
        }
        let mut map = FloorUncertaintyMap::from_fit(
            &cal.camera,
            &cal.covariance,
            &boards,
            &fitted,
            (cal.camera.width / 32).max(8),
        )?;
        // The other lens models the held-out views could not tell from the chosen one, each
        // with the floor its own calibration locates: where they part, no model is known.
        // So are those fitting the views clearly better than the chosen one: the chosen
        // one's covariance does not cover its misfit (a fisheye kept on a 110° rational
        // lens vouched for a floor 4.6 mm off).
        let others: Vec<(crate::CameraModel, crate::FloorToCamera)> = model_comparison
            .iter()
            .filter(|s| {
                !s.chosen
                    && (s.held_out_within(&model_comparison)
                        || s.fits_clearly_better_than(cal.rms_px))
            })
            .filter_map(|s| s.camera)
            .chain(fitting_better.iter().copied())
            .filter_map(|cam| {
                let b = FloorBoards::locate(&cam, &fviews, &floor_board, corner_sigma_px).ok()?;
                let f = b.fit_parameters(&cam);
                Some((cam, b.floor(&f)))
            })
            .collect();
        map.add_model_spread(&cal.camera, &boards.floor(&fitted), &others);
        floor_uncertainty = Some(map);
        Some(plane)
    };
    let file = CameraFile {
        format: CAMERA_FORMAT.into(),
        camera: cal.camera,
        rms_px: cal.rms_px,
        std: Some(cal.std),
        views: cal.views.clone(),
        skipped,
        board: Some(*board),
        floor,
        covariance: Some(
            cal.covariance
                .row_iter()
                .map(|r| r.iter().copied().collect())
                .collect(),
        ),
        model_comparison,
        floor_uncertainty,
    };
    Ok(Session { file, notes })
}

/// Corners of two views closer than this (RMS, pixels) make them the same view.
pub const SAME_VIEW_RMS_PX: f64 = 0.5;

/// Whether the views show a ChArUco board in the layout before OpenCV 4.6 (see
/// [`crate::charuco`]); an error when some do and some do not, as one board has one layout:
/// the views of the other layout would be calibrated on corners a square off.
fn check_layouts<'a>(
    views: impl Iterator<Item = &'a BoardView> + Clone,
) -> Result<bool, CalibError> {
    let legacy = views.clone().find(|v| v.legacy_layout);
    let current = views.clone().find(|v| !v.legacy_layout);
    match (legacy, current) {
        (Some(l), Some(c)) => Err(CalibError::Input(format!(
            "{} shows a ChArUco board in the layout OpenCV drew before 4.6 (top-left square white, holding marker 0), but {} one in the layout of OpenCV 4.6 on (top-left square black), or too little of the board to tell: one board has one layout; take the views of one board, each with its board's left and right columns in sight",
            l.image, c.image
        ))),
        (l, _) => Ok(l.is_some()),
    }
}

/// Hand-held boards located this far beyond the floor (a share of the camera's height) are
/// beyond chance: a board is placed along the line of sight to a fraction of a percent.
const BEYOND_FLOOR_SHARE: f64 = 0.1;

/// A warning when most hand-held boards (`poses` of `views`) lie beyond the floor `plane`:
/// held under a ceiling camera a board is nearer than the floor, so the floor is too near,
/// which a floor board larger than the `square_m` given for it (by `option`) does, scaling
/// every floor distance and the camera's height down by the ratio of the two squares. One
/// flat board alone cannot tell its own scale, and the hand-held boards' distances are the
/// only other scale in the session. Views taken before the camera was mounted, or a board
/// held up to a far wall, can lie beyond the floor: hence the median board and a warning
/// (`synth calib` holds one board in twenty beyond a right floor).
fn views_beyond_floor_note(
    poses: &[crate::BoardToCamera],
    views: &[BoardView],
    plane: &crate::FloorPlane,
    option: &str,
    square_m: f64,
) -> Option<String> {
    let up = plane.floor_to_camera.0.rotation * nalgebra::Vector3::z();
    let height_m = plane.camera_height_m;
    // Each hand-held board's centre: its depth below the camera along the floor's normal.
    let depths: Vec<f64> = poses
        .iter()
        .zip(views)
        .map(|(pose, v)| {
            let n = v.object_points.len().max(1) as f64;
            let c = v
                .object_points
                .iter()
                .map(|p| p.coords)
                .sum::<nalgebra::Vector3<f64>>()
                / n;
            -(pose.0 * nalgebra::Point3::from(c)).coords.dot(&up)
        })
        .collect();
    let median_m = crate::select::median(&depths);
    let limit_m = height_m * (1.0 + BEYOND_FLOOR_SHARE);
    if !(height_m > 0.0 && median_m > limit_m) {
        return None;
    }
    let beyond = depths.iter().filter(|d| **d > limit_m).count();
    Some(format!(
        "warning: {beyond} of the {} hand-held boards lie beyond the floor: the median board is {median_m:.2} m below the camera, where the floor boards put the floor {height_m:.2} m below it, yet a board held under a ceiling camera is nearer than the floor. If the views were taken with the camera in place, the floor board's squares are larger than {option} {square_m} m (by this median, at least {:.3} m), and the camera's height and every floor distance come out too small by the ratio of the two: pass the floor board's own square side as --floor-square",
        views.len(),
        square_m * median_m / height_m
    ))
}

/// Skips the one floor view of a ChArUco board whose markers read as the other layout than
/// the hand-held views' (`legacy_layout`, see [`check_layouts`]): markers small or blurred
/// (far out in a fisheye's image) can agree a little better with the other layout by
/// chance, and one such view aborted the whole calibration. The layout's verdict needs
/// several views: two or more floor views reading so are left to [`check_layouts`]. The first
/// floor view fixes the floor frame, so it is not skipped but refused.
fn odd_layout_floor_view(
    mut fviews: Vec<BoardView>,
    legacy_layout: bool,
    skipped: &mut Vec<SkippedView>,
) -> Result<Vec<BoardView>, CalibError> {
    let odd: Vec<usize> = (0..fviews.len())
        .filter(|&k| fviews[k].legacy_layout != legacy_layout)
        .collect();
    let [k] = odd.as_slice() else {
        return Ok(fviews);
    };
    if fviews.len() < 2 {
        return Ok(fviews);
    }
    let (this, other) = if legacy_layout {
        ("OpenCV 4.6 on", "before 4.6")
    } else {
        ("before 4.6", "OpenCV 4.6 on")
    };
    let reason = format!(
        "unreadable: its markers fit the ChArUco layout of {this} a little better than the layout of {other} every other view shows, as markers too small or blurred to read reliably can"
    );
    if *k == 0 {
        return Err(CalibError::Input(format!(
            "the first floor view {}, which fixes the floor frame's origin and axes, is {reason}; retake it with the board nearer the image's centre, or give first the floor view whose board should be the origin",
            fviews[0].image
        )));
    }
    let v = fviews.remove(*k);
    skipped.push(SkippedView {
        image: v.image,
        reason,
    });
    Ok(fviews)
}

/// A note when the floor frame's x axis (along the board's rows of `cols` corners) runs up or
/// down the first floor view: a board whose counts were given rows first (6x9 for a 9x6) is
/// found all the same, with the floor frame turned 90° from the one meant.
fn turned_floor_note(first: &BoardView, board: &BoardSpec) -> Option<String> {
    if board.is_charuco() {
        return None;
    }
    // A square board looks the same turned a quarter: which of its corners OpenCV numbers
    // first, and so the floor frame's origin and axes, is the image's to decide.
    if board.cols == board.rows {
        return Some(format!(
            "warning: the board has as many inner corners along one side as along the other ({}x{}), so it looks alike turned a quarter: the floor frame's origin and axes, which the first floor view {} fixes, may sit at any of its corners (the floor plane itself holds); use a board whose two counts differ (e.g. 9x6) for a frame you can name",
            board.cols, board.rows, first.image
        ));
    }
    let cols = board.cols as usize;
    let x_axis = first.corners.get(cols - 1)? - first.corners.first()?;
    (x_axis.y.abs() > x_axis.x.abs()).then(|| {
        format!(
            "note: the floor frame's x axis runs along the board's rows of {} corners, which run {} the image in {}: if the board's rows of {} corners were meant (counts given rows first), give --board {}x{}; the floor frame is otherwise turned 90° from the one meant",
            board.cols,
            if x_axis.y > 0.0 { "down" } else { "up" },
            first.image,
            board.rows,
            board.rows,
            board.cols
        )
    })
}

/// Views from one folder that calibrate to a focal length this far (a fraction) from another
/// folder's are of another camera or zoom: subsets of one camera's views agree within a
/// percent or two.
const FOLDER_FOCAL_SHARE: f64 = 0.05;

/// The fewest views a folder needs to be calibrated on its own for [`check_one_camera`].
const FOLDER_MIN_VIEWS: usize = 5;

/// Refuses views from several folders whose folders calibrate to different cameras: two
/// sessions' views given together (`a/view_*.png b/view_*.png`) fit one camera whose focal
/// length is neither's, the distortion taking up the difference, with a sub-pixel RMS (two
/// cameras of 478 and 405 px gave 448.6 px ± 1.5, exit 0). `fx` is the calibration of all
/// the views.
fn check_one_camera(
    views: &[BoardView],
    board: &BoardSpec,
    model: LensModel,
    fx: f64,
) -> Result<(), CalibError> {
    let folder = |v: &BoardView| {
        Path::new(&v.image)
            .parent()
            .map(|p| p.display().to_string())
            .unwrap_or_default()
    };
    let mut folders: Vec<String> = views.iter().map(folder).collect();
    folders.sort();
    folders.dedup();
    if folders.len() < 2 {
        return Ok(());
    }
    let per_folder: Vec<(String, usize, f64)> = folders
        .par_iter()
        .filter_map(|f| {
            let own: Vec<BoardView> = views.iter().filter(|v| folder(v) == *f).cloned().collect();
            if own.len() < FOLDER_MIN_VIEWS {
                return None;
            }
            let c = calibrate(&own, board, model).ok()?;
            Some((f.clone(), own.len(), c.camera.intrinsics.fx))
        })
        .collect();
    let lo = per_folder.iter().min_by(|a, b| a.2.total_cmp(&b.2));
    let hi = per_folder.iter().max_by(|a, b| a.2.total_cmp(&b.2));
    if let (Some(lo), Some(hi)) = (lo, hi) {
        if (hi.2 - lo.2) / lo.2 > FOLDER_FOCAL_SHARE {
            let name = |f: &str| {
                if f.is_empty() {
                    ".".to_string()
                } else {
                    f.to_string()
                }
            };
            return Err(CalibError::Input(format!(
                "the views are of two cameras or zooms: the {} views in {}/ calibrate to fx {:.1} px and the {} in {}/ to fx {:.1} px, {:.0} % apart, where one camera's views agree within a few percent (all together fit fx {fx:.1} px, neither's); calibrate each folder's views on their own",
                lo.1,
                name(&lo.0),
                lo.2,
                hi.1,
                name(&hi.0),
                hi.2,
                100.0 * (hi.2 - lo.2) / lo.2
            )));
        }
    }
    Ok(())
}

/// Drops views that repeat an earlier one (the same photo given twice, or the board not
/// moved between shots), noting each as skipped: they add no constraint, yet weigh their pose
/// twice in the fit.
fn distinct_views(views: Vec<BoardView>, skipped: &mut Vec<SkippedView>) -> Vec<BoardView> {
    let mut kept: Vec<BoardView> = Vec::with_capacity(views.len());
    for v in views {
        let same = kept.iter().find(|k| {
            let n = k.corners.len().max(1) as f64;
            let ss: f64 = k
                .corners
                .iter()
                .zip(&v.corners)
                .map(|(a, b)| (a - b).norm_squared())
                .sum();
            k.ids == v.ids && (ss / n).sqrt() < SAME_VIEW_RMS_PX
        });
        match same {
            // The same file named again (a glob and a name overlapping) is said as such, not
            // as "the same view as" itself.
            Some(k) if k.image == v.image => skipped.push(SkippedView {
                image: v.image.clone(),
                reason: "the same file given again".into(),
            }),
            Some(k) => skipped.push(SkippedView {
                image: v.image.clone(),
                reason: format!(
                    "the same view as {} (corners within {SAME_VIEW_RMS_PX} px)",
                    k.image
                ),
            }),
            None => kept.push(v),
        }
    }
    kept
}

/// Refuses a `--board` that counts fewer corners than the checkerboard in the views has (a
/// ChArUco board's markers name every corner, so it cannot be taken for a part of itself):
/// when the first view, or two views or more, show the grid going on past the corners found.
fn check_board_size(views: &[BoardView], board: &BoardSpec) -> Result<(), CalibError> {
    if board.is_charuco() {
        return Ok(());
    }
    let larger: Vec<(&BoardView, (u32, u32))> = views
        .par_iter()
        .filter_map(|v| {
            crate::detect::larger_board_around(Path::new(&v.image), board, &v.corners)
                .map(|size| (v, size))
        })
        .collect();
    let first_shows = views
        .first()
        .is_some_and(|f| larger.iter().any(|(v, _)| v.image == f.image));
    if !(first_shows || larger.len() >= 2) {
        return Ok(());
    }
    // The size most views show (a view cut by the image's edge shows less of the board).
    let larger: Vec<(&BoardView, (u32, u32))> = larger
        .into_iter()
        .map(|(v, s)| (v, crate::detect::oriented_like(s, board)))
        .collect();
    let mut sizes: Vec<(u32, u32)> = larger.iter().map(|(_, s)| *s).collect();
    sizes.sort_by_key(|&(c, r)| std::cmp::Reverse(c * r));
    let example = larger
        .iter()
        .find(|(_, s)| *s == sizes[0])
        .map_or("", |(v, _)| v.image.as_str());
    let seen = crate::detect::board_size_confirmed(Path::new(example), sizes[0], board);
    let (c, r) = seen.size;
    let (shows, pass) = if seen.confirmed {
        (
            format!("a {c}x{r} board"),
            format!("pass --board {c}x{r} (inner corners)"),
        )
    } else {
        (
            format!("a board of at least {c}x{r} inner corners"),
            "count its INNER corners (one fewer than the squares along each side) and pass them as --board".to_string(),
        )
    };
    Err(CalibError::Input(format!(
        "{example} shows {shows}, but --board {}x{} finds only part of it ({} of {} views show more corners around or between the corners found; a part found at another place in each view moves the floor origin and fits no one camera); {pass}",
        board.cols,
        board.rows,
        larger.len(),
        views.len()
    )))
}

/// Detects the board in every image in parallel.
fn detect_all(
    paths: &[PathBuf],
    board: &BoardSpec,
    on_image: &(dyn Fn() + Sync),
) -> Result<Vec<Detection>, CalibError> {
    paths
        .par_iter()
        .map(|p| {
            let d = detect_file(p, board);
            on_image();
            d
        })
        .collect()
}

type Sizes = Vec<(String, (u32, u32))>;

fn split(detections: Vec<Detection>) -> (Vec<BoardView>, Vec<SkippedView>, Sizes) {
    let mut views = Vec::new();
    let mut skipped = Vec::new();
    let mut sizes = Vec::new();
    for d in detections {
        match d {
            Detection::Found(v) => {
                sizes.push((v.image.clone(), v.size));
                views.push(v);
            }
            Detection::NotFound {
                image,
                size,
                reason,
            } => {
                sizes.push((image.clone(), size));
                skipped.push(SkippedView { image, reason });
            }
        }
    }
    (views, skipped, sizes)
}

fn check_sizes(sizes: &[(String, (u32, u32))]) -> Result<(), CalibError> {
    if let Some((first, s0)) = sizes.first() {
        if let Some((other, s)) = sizes.iter().find(|(_, s)| s != s0) {
            // Width and height swapped: a photo turned a quarter (by a viewer, or saved
            // upright from a camera held on its side), which the resolution alone hid.
            let turned = if (s.1, s.0) == *s0 {
                format!(
                    ", turned 90° against it: turn {other} back (and any other image so turned), as the camera recorded it"
                )
            } else {
                String::new()
            };
            return Err(CalibError::Input(format!(
                "{other} is {}x{} but {first} is {}x{}{turned}: all images must come from one camera at one resolution",
                s.0,
                s.1,
                s0.0,
                s0.1
            )));
        }
    }
    Ok(())
}

fn no_board_error(paths: &[PathBuf], board: &BoardSpec, what: &str) -> CalibError {
    if let BoardTarget::Charuco { dictionary, .. } = board.target {
        return no_charuco_error(paths, board, dictionary, what);
    }
    let hint = paths
        .iter()
        .take(3)
        .find_map(|p| guess_board_size(p, board))
        .map(|(c, r)| format!(" A {c}x{r} board was found instead: pass --board {c}x{r}."))
        .or_else(|| {
            paths.iter().take(3).find_map(|p| crate::charuco::markers_seen(p)).map(|(d, n)| {
                format!(
                    " The images show a ChArUco board ({n} markers of dictionary {d} in one): pass --target charuco --dictionary {d}, with --board counting its squares and --marker the side of a marker."
                )
            })
        })
        .unwrap_or_default();
    CalibError::Input(format!(
        "no {}x{} checkerboard found in any of the {} {what} image(s): --board counts INNER corners \
         (a board of {}x{} squares has {}x{} inner corners).{hint}",
        board.cols,
        board.rows,
        paths.len(),
        board.cols + 1,
        board.rows + 1,
        board.cols,
        board.rows
    ))
}

fn no_charuco_error(
    paths: &[PathBuf],
    board: &BoardSpec,
    dictionary: ArucoDictionary,
    what: &str,
) -> CalibError {
    let reason = paths.first().map(|p| {
        let reason = match detect_file(p, board) {
            Ok(Detection::NotFound { reason, .. }) => reason,
            Ok(Detection::Found(_)) => "the board was found".into(),
            Err(e) => e.to_string(),
        };
        (p, reason)
    });
    // Markers too small to use are a matter of pixels: the options are not blamed.
    let options = if reason
        .as_ref()
        .is_some_and(|(_, r)| r.contains("too few pixels"))
    {
        ""
    } else {
        " --board counts the ChArUco board's squares and --dictionary names its markers."
    };
    let first = reason.map(|(p, r)| format!(" In {}: {r}.", p.display()));
    let hint = paths
        .iter()
        .take(3)
        .find_map(|p| crate::charuco::guess_dictionary(p, dictionary))
        .map(|(d, n)| format!(" {n} markers of dictionary {d} were found: pass --dictionary {d}."))
        .or_else(|| {
            let p = paths.first()?;
            let (c, r) = crate::detect::checkerboard_shown(p, board)?;
            Some(format!(
                " {} shows a plain checkerboard of {c}x{r} inner corners and no ArUco marker: leave out --target charuco, --marker and --dictionary, and pass --board {c}x{r}.",
                p.display()
            ))
        })
        .unwrap_or_default();
    CalibError::Input(format!(
        "no {} found in any of the {} {what} image(s):{options}{}{hint}",
        crate::charuco::board_name(board),
        paths.len(),
        first.unwrap_or_default()
    ))
}

/// The calibration as `odocal calibrate` prints it: every number with its unit and
/// uncertainty, one line each.
pub fn summary(f: &CameraFile) -> Vec<String> {
    let mut out = Vec::new();
    let k = f.camera.intrinsics;
    let model = f.camera.distortion.model;
    out.push(format!(
        "calibration of a {}x{} camera ({model} lens model) from {} views ({} skipped); RMS reprojection error {:.3} px",
        f.camera.width,
        f.camera.height,
        f.views.len(),
        f.skipped.len(),
        f.rms_px
    ));
    if let Some(b) = f.board.filter(|b| b.is_charuco()) {
        let mut n: Vec<usize> = f.views.iter().map(|v| v.corners_px.len()).collect();
        n.sort_unstable();
        if let (Some(lo), Some(hi)) = (n.first(), n.last()) {
            out.push(format!(
                "  {}: {} ChArUco corners in all, per view min {lo}, median {}, max {hi} of {}",
                crate::charuco::board_name(&b),
                n.iter().sum::<usize>(),
                n[n.len() / 2],
                b.cols * b.rows
            ));
        }
    }
    if !f.model_comparison.is_empty() {
        out.push(
            "  lens models judged on views left out of their calibration (5-fold, RMS px):"
                .to_string(),
        );
        for s in &f.model_comparison {
            let held = match (s.held_out_rms_px, &s.failure) {
                (Some(e), _) => format!("held out {e:.3} px"),
                (None, Some(why)) => format!("failed: {why}"),
                (None, None) => "not judged".into(),
            };
            let fit = s
                .fit_rms_px
                .map(|e| format!("fit {e:.3} px, "))
                .unwrap_or_default();
            out.push(format!(
                "    {:9} {:2} parameters: {fit}{held}{}",
                s.model.name(),
                s.parameters,
                if s.chosen { "  <- chosen" } else { "" }
            ));
        }
        out.push(format!(
            "    (the first of pinhole5, fisheye, rational whose median view held out is within {:.0} % of the best, or whose views held out are so view by view (median), is chosen)",
            crate::select::SIMPLER_WITHIN * 100.0
        ));
    }
    let sd = f.std.clone();
    let s = |v: Option<f64>| v.map(|x| format!("± {x:.3}")).unwrap_or_default();
    out.push(format!(
        "  fx = {:10.3} px {}",
        k.fx,
        s(sd.as_ref().map(|x| x.fx))
    ));
    out.push(format!(
        "  fy = {:10.3} px {}",
        k.fy,
        s(sd.as_ref().map(|x| x.fy))
    ));
    out.push(format!(
        "  cx = {:10.3} px {}",
        k.cx,
        s(sd.as_ref().map(|x| x.cx))
    ));
    out.push(format!(
        "  cy = {:10.3} px {}",
        k.cy,
        s(sd.as_ref().map(|x| x.cy))
    ));
    let d = f.camera.distortion.coefficients();
    for (i, name) in model.coefficient_names().iter().enumerate() {
        let e = sd
            .as_ref()
            .and_then(|x| x.distortion.get(i))
            .map(|x| format!("± {x:.5}"))
            .unwrap_or_default();
        out.push(format!("  {name} = {:10.5}    {e}", d[i]));
    }
    out.push(
        "  (± is one standard deviation from the covariance at the optimum, board poses marginalised out)"
            .to_string(),
    );
    let mut worst = f.views.clone();
    worst.sort_by(|a, b| b.rms_px.total_cmp(&a.rms_px));
    let list: Vec<String> = worst
        .iter()
        .take(3)
        .map(|v| format!("{} {:.3} px", name_among(&f.views, &v.image), v.rms_px))
        .collect();
    out.push(format!(
        "  worst views (RMS reprojection): {}",
        list.join(", ")
    ));
    if let Some(rms) = held_out_rms_px(&f.views) {
        out.push(format!(
            "  held-out views (each left out of the calibration): RMS {rms:.3} px; worst {}",
            worst_views(&f.views, 3).join(", ")
        ));
    }
    if let Some(cov) = f.covariance_matrix() {
        let map = UncertaintyMap::new(&f.camera, &cov, (f.camera.width / 32).max(8));
        let side_px = f.camera.width.max(f.camera.height);
        if let Some(median) = map.median_px() {
            out.push(format!(
                "  projection uncertainty of a camera-frame direction (1σ, worst direction, from the covariance): median {}, largest {} over the image (an upper bound on the floor, whose plane the same intrinsics fix)",
                crate::uncertainty::far_px(median, side_px, 3),
                crate::uncertainty::far_px(map.max_px(), side_px, 3)
            ));
        }
    }
    if let Some(fl) = &f.floor {
        out.push(format!(
            "floor plane from {} view(s): corners within {:.2} mm RMS of the plane; camera {:.4} m above the floor",
            fl.views.len(),
            fl.plane_rms_m * 1000.0,
            fl.camera_height_m
        ));
        if let Some((median, max)) = f
            .floor_uncertainty
            .as_ref()
            .and_then(|m| m.median_and_max_mm())
        {
            out.push(format!(
                "  floor position uncertainty (1σ along the worst direction, from the intrinsics' covariance and the floor boards' corner noise): median {}, largest {} over the image where it sees the floor",
                crate::floor_uncertainty::far_mm(median, 3),
                crate::floor_uncertainty::far_mm(max, 3)
            ));
        }
        if let Some(r) = f
            .floor_uncertainty
            .as_ref()
            .and_then(|m| m.vouched_reach(&f.camera, &fl.floor_to_camera))
        {
            out.push(format!("  {}", r.sentence(f.model_comparison.is_empty())));
        }
    } else {
        out.push(
            "no floor plane (pass --floor images of the board lying on the floor to track robots)"
                .to_string(),
        );
    }
    out
}

/// A view's image by its file name, or by its whole path when another view's file has the
/// same name (views from two folders, the very case the worst-views lists warn of).
fn name_among(views: &[crate::ViewResidual], image: &str) -> String {
    let name = short(image);
    if views.iter().filter(|v| short(&v.image) == name).count() > 1 {
        image.to_string()
    } else {
        name
    }
}

fn short(p: &str) -> String {
    Path::new(p)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--square 1e-6` (a size in other units) calibrated, the camera "0.00 m above the
    /// floor", exit 0: squares under 2 mm are refused up front for both board kinds.
    #[test]
    fn implausibly_small_squares_are_refused_in_metres() {
        for sq in [1e-6, 1e-3, 0.0, 1.0] {
            let e = BoardSpec::parse("9x6", sq).unwrap_err().to_string();
            assert!(
                e.contains("the square size is in metres") && e.contains("2 mm to 1 m"),
                "{e}"
            );
            let e = BoardSpec::parse_charuco("11x8", sq, sq * 0.75, "4X4_50")
                .unwrap_err()
                .to_string();
            assert!(e.contains("the square size is in metres"), "{e}");
        }
        assert!(BoardSpec::parse("9x6", 0.005).is_ok());
    }

    /// 12 views of a 70° lens calibrated as a fisheye, one of which the fisheye calibration
    /// of the others could not locate, while pinhole5 predicts every view left out: the
    /// model is blamed and the one that fits named, never the views (no "inf %" either);
    /// without a model that predicts them, the views are.
    #[test]
    fn an_unlocated_view_another_model_predicts_blames_the_model() {
        let views: Vec<crate::ViewResidual> = (0..12)
            .map(|k| crate::ViewResidual {
                image: format!("view_{k:02}.png"),
                rms_px: 0.06,
                held_out_rms_px: (k != 3).then_some(0.065),
                corners_px: Vec::new(),
            })
            .collect();
        let pinhole = || vec![(LensModel::Pinhole5, 0.05, 0.052)];
        let notes = consistency_notes(LensModel::Fisheye, 0.06, &views, 1, &pinhole);
        assert_eq!(notes.len(), 1, "{notes:?}");
        let n = &notes[0];
        assert!(
            n.contains("the fisheye lens model does not predict these views: 1 of the 12 views could not be located at all")
                && n.contains("yet the pinhole5 model predicts every view left out of its calibration within its fit (held-out RMS 0.052 px against 0.050 px)")
                && n.contains("calibrate with --model pinhole5"),
            "{n}"
        );
        assert!(!n.contains("inf") && !n.contains("NaN"), "{n}");
        let none = || vec![(LensModel::Pinhole5, 0.05, 0.5)];
        let notes = consistency_notes(LensModel::Fisheye, 0.06, &views, 1, &none);
        assert!(
            notes[0].contains("the views do not fit one camera"),
            "{notes:?}"
        );
    }

    /// The fits of `synth calib --views 12 --floor-views 3` with the model fixed: a 150°
    /// fisheye at 640x360 as pinhole5 misfits by under a pixel, 12 times the others' fit, and
    /// was written 8.6 % off (or blamed on a floor view); a 110° rational lens as fisheye
    /// fits 75 % worse and its floor was vouched for 5.3 mm off the truth.
    #[test]
    fn a_fixed_model_another_fits_far_better_is_refused_and_clearly_better_warned() {
        let e = judge_fixed_model(
            LensModel::Pinhole5,
            0.775,
            &[(LensModel::Rational, 0.064), (LensModel::Fisheye, 0.064)],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("--model pinhole5 does not fit") && e.contains("--model rational"),
            "{e}"
        );
        let w = judge_fixed_model(
            LensModel::Fisheye,
            0.090,
            &[(LensModel::Pinhole5, 0.9), (LensModel::Rational, 0.051)],
        )
        .expect("not refused")
        .expect("warned");
        assert!(
            w.starts_with(
                "warning: --model fisheye fits the views 76 % worse than the rational model"
            ),
            "{w}"
        );
        // Leaving --model out keeps a model the held-out views cannot tell apart (OpenCV's
        // photos: pinhole5 again, 8 % worse): only the named model is advised.
        assert!(
            w.ends_with("Calibrate with --model rational") && !w.contains("leave --model out"),
            "{w}"
        );
        // Extra parameters that are no truer lower the fit by well under 5 %.
        let none = judge_fixed_model(
            LensModel::Pinhole5,
            0.100,
            &[(LensModel::Rational, 0.098), (LensModel::Fisheye, 0.2)],
        )
        .expect("not refused");
        assert!(none.is_none(), "{none:?}");
    }
}
