//! Choosing the lens model by held-out reprojection error: each model is calibrated with a
//! fold of the views left out, the left-out boards are located with that calibration
//! (solvePnP, their pose fitted alone) and their corners' reprojection error measured. A
//! model with too many parameters fits the calibration views but not the held-out ones; one
//! with too few fits neither (mrcal's advice for choosing a model). Models are compared by
//! the median view's held-out error: a view reaching where no other does is extrapolated to
//! when left out, and its error (9.6 px for the true rational lens of a 110° camera at
//! 800x450, against 0.05 px for the rest) would otherwise decide the choice for a model
//! that misfits every view.

use serde::{Deserialize, Serialize};

use crate::{calibrate, solve_pnp, BoardSpec, BoardView, CalibError, LensModel};

/// Folds of the leave-views-out cross-validation (fewer when there are fewer views).
pub const FOLDS: usize = 5;

/// A model is chosen over a more complex one unless that one's median held-out error is
/// lower by more than this fraction.
pub const SIMPLER_WITHIN: f64 = 0.05;

/// The order in which models are preferred when they fit equally well: OpenCV's default,
/// then the fisheye model (fewer coefficients than the rational one), then the rational.
pub const PREFERENCE: [LensModel; 3] =
    [LensModel::Pinhole5, LensModel::Fisheye, LensModel::Rational];

/// One lens model's calibration judged on views it did not see.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelScore {
    /// The lens model.
    pub model: LensModel,
    /// Number of intrinsic parameters (fx fy cx cy and the coefficients).
    pub parameters: usize,
    /// RMS reprojection error of the calibration on all views, pixels.
    pub fit_rms_px: Option<f64>,
    /// RMS reprojection error of the views when left out, pixels (`None` if the model
    /// failed on some fold).
    pub held_out_rms_px: Option<f64>,
    /// The median over the views of their held-out RMS, pixels: what models are compared by.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held_out_median_px: Option<f64>,
    /// The held-out RMS of each view, in input order, pixels.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub view_held_out_rms_px: Vec<f64>,
    /// Why the model could not be judged, if it could not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// Whether this model was chosen.
    pub chosen: bool,
    /// The model's calibration on all views (not kept in files: the chosen one is the
    /// file's camera).
    #[serde(skip)]
    pub camera: Option<crate::CameraModel>,
}

/// The held-out reprojection error of `model` on `views`: per view, pixels.
pub fn held_out_errors(
    views: &[BoardView],
    board: &BoardSpec,
    model: LensModel,
) -> Result<Vec<f64>, CalibError> {
    let folds = FOLDS.min(views.len());
    if views.len() < crate::session::AUTO_MIN_VIEWS {
        return Err(CalibError::Input(format!(
            "judging a lens model on held-out views needs at least {} views, there are {}: add views, or give the lens model (--model pinhole5, or fisheye or rational for a wide lens)",
            crate::session::AUTO_MIN_VIEWS,
            views.len()
        )));
    }
    let mut out = vec![f64::NAN; views.len()];
    // A fold OpenCV cannot calibrate (its fisheye initialisation asserts on some subsets of
    // views it calibrates whole) is tried again one view at a time: one such fold used to
    // drop the model, and `auto` chose another that fitted a true fisheye 4.5σ off.
    let mut plan: Vec<Vec<usize>> = (0..folds)
        .map(|fold| (0..views.len()).filter(|i| i % folds == fold).collect())
        .collect();
    let mut k = 0;
    while k < plan.len() {
        let held: Vec<usize> = plan[k].clone();
        k += 1;
        let train: Vec<BoardView> = views
            .iter()
            .enumerate()
            .filter(|(i, _)| !held.contains(i))
            .map(|(_, v)| v.clone())
            .collect();
        let cal = match calibrate(&train, board, model) {
            Ok(cal) => cal,
            Err(_) if held.len() > 1 => {
                plan.extend(held.iter().map(|&i| vec![i]));
                continue;
            }
            Err(e) => return Err(e),
        };
        for (i, v) in views.iter().enumerate().filter(|(i, _)| held.contains(i)) {
            let Some(pose) = solve_pnp(
                &cal.camera,
                &v.object_points,
                &v.corners,
                opencv::calib3d::SOLVEPNP_ITERATIVE,
            )?
            else {
                return Err(CalibError::Input(format!(
                    "{}: the board cannot be located with the {model} calibration of the other views",
                    v.image
                )));
            };
            let mut ss = 0.0;
            for (p, x) in v.object_points.iter().zip(&v.corners) {
                ss += match cal.camera.project(&(pose * p)) {
                    Some(q) => (q - x).norm_squared(),
                    None => f64::INFINITY,
                };
            }
            out[i] = (ss / v.corners.len().max(1) as f64).sqrt();
        }
    }
    Ok(out)
}

/// Scores every model and marks the chosen one: the first in [`PREFERENCE`] whose held-out
/// error is within [`SIMPLER_WITHIN`] of the best.
pub fn compare_models(
    views: &[BoardView],
    board: &BoardSpec,
    on_model: &(dyn Fn(LensModel) + Sync),
) -> Result<Vec<ModelScore>, CalibError> {
    let mut scores: Vec<ModelScore> = PREFERENCE
        .iter()
        .map(|&model| {
            let n_params = 4 + model.coefficient_names().len();
            let fit = calibrate(views, board, model);
            let held = held_out_errors(views, board, model);
            on_model(model);
            let (held_out_rms_px, view_held_out_rms_px, failure) = match (&fit, held) {
                (Ok(_), Ok(v)) if v.iter().all(|e| e.is_finite()) => (Some(rms(&v)), v, None),
                (Ok(_), Ok(_)) => (None, vec![], Some("a held-out view did not project".into())),
                (Err(e), _) => (None, vec![], Some(e.to_string())),
                (_, Err(e)) => (None, vec![], Some(e.to_string())),
            };
            ModelScore {
                model,
                parameters: n_params,
                held_out_median_px: held_out_rms_px.map(|_| median(&view_held_out_rms_px)),
                camera: fit.as_ref().ok().map(|c| c.camera),
                fit_rms_px: fit.ok().map(|c| c.rms_px),
                held_out_rms_px,
                view_held_out_rms_px,
                failure,
                chosen: false,
            }
        })
        .collect();
    let best = best_held_out_px(&scores);
    if !best.is_finite() {
        // Every model failed on the same views: OpenCV's default model's reason is the one
        // a user can act on (a degenerate set, too few views).
        let why = scores
            .first()
            .and_then(|s| s.failure.clone())
            .unwrap_or_else(|| "no lens model could be calibrated from these views".into());
        return Err(CalibError::Input(why));
    }
    mark_chosen(&mut scores);
    Ok(scores)
}

/// Marks the first model in [`PREFERENCE`] order the held-out views cannot tell from the
/// best ([`ModelScore::fits_as_well`]) as chosen.
pub fn mark_chosen(scores: &mut [ModelScore]) {
    let tied: Vec<bool> = scores.iter().map(|s| s.fits_as_well(scores)).collect();
    if let Some(k) = tied.iter().position(|t| *t) {
        scores[k].chosen = true;
    }
}

/// The RMS of per-view errors, pixels.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|e| e * e).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// The median of per-view errors, pixels (NaN when there are none).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// The lowest median held-out error of the models judged, pixels (infinite when none was).
pub fn best_held_out_px(scores: &[ModelScore]) -> f64 {
    scores
        .iter()
        .filter_map(|s| s.held_out_median_px)
        .fold(f64::INFINITY, f64::min)
}

/// A model whose fit to all the views is worse than another's by more than this fraction
/// misfits the lens: extra parameters that are no truer lower the RMS by about their share
/// of the residuals (4 more parameters over 10 views of 54 corners: 0.2 %), and models the
/// lens tells apart differ by 14–150 % (a 110° rational lens at 800x450 and 640x480).
pub const CLEARLY_BETTER_FIT: f64 = 0.05;

impl ModelScore {
    /// Whether the held-out views cannot tell this model from the best one of `scores` (the
    /// lowest median held-out error): its median is within [`SIMPLER_WITHIN`] of it, or view
    /// by view (the same corners held out under both) the median of its errors over the best
    /// one's is. The medians alone part on one view's error in a set of 8 (pinhole5 0.052 px
    /// against fisheye 0.044 on a pinhole lens, each view but one within 4 % of the other),
    /// and auto chose the fisheye with a principal point 3σ off.
    pub fn fits_as_well(&self, scores: &[ModelScore]) -> bool {
        if self.held_out_within(scores) {
            return true;
        }
        let best_px = best_held_out_px(scores);
        let Some(best) = scores
            .iter()
            .find(|s| s.held_out_median_px == Some(best_px))
        else {
            return false;
        };
        let n = self.view_held_out_rms_px.len();
        if n == 0 || best.view_held_out_rms_px.len() != n {
            return false;
        }
        let ratios: Vec<f64> = self
            .view_held_out_rms_px
            .iter()
            .zip(&best.view_held_out_rms_px)
            .map(|(a, b)| a / b.max(1e-12))
            .collect();
        median(&ratios) <= 1.0 + SIMPLER_WITHIN
    }

    /// Whether this model's median held-out error is within [`SIMPLER_WITHIN`] of the best
    /// one of `scores`: the models whose floors the chosen one's is vouched against. Not
    /// view by view as [`Self::fits_as_well`] also judges, which keeps a near tie for the
    /// simpler model: a model that ties only view by view fits the views no better, and
    /// adding its floor spread took 0.18 m off a ChArUco calibration's vouched floor
    /// whose error was 0.53 mm at most.
    pub fn held_out_within(&self, scores: &[ModelScore]) -> bool {
        let best_px = best_held_out_px(scores);
        self.held_out_median_px
            .is_some_and(|e| e <= best_px * (1.0 + SIMPLER_WITHIN))
    }

    /// Whether this model fits all the views clearly better than one fitting them to
    /// `other_fit_px` ([`CLEARLY_BETTER_FIT`]).
    pub fn fits_clearly_better_than(&self, other_fit_px: f64) -> bool {
        self.fit_rms_px
            .is_some_and(|e| e * (1.0 + CLEARLY_BETTER_FIT) < other_fit_px)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model's score from its fit and its views' held-out errors, px.
    fn score(model: LensModel, fit: f64, v: &[f64]) -> ModelScore {
        ModelScore {
            model,
            parameters: 4 + model.coefficient_names().len(),
            fit_rms_px: Some(fit),
            held_out_rms_px: Some(rms(v)),
            held_out_median_px: Some(median(v)),
            view_held_out_rms_px: v.to_vec(),
            failure: None,
            chosen: false,
            camera: None,
        }
    }

    /// The per-view held-out errors of a 110° rational lens at 800x450 (`synth calib --seed
    /// 5 --views 10`): one view reaching where no other does made the true model's RMS 3.0 px
    /// and the choice fisheye's, which put the floor 4.7 mm off where it was vouched for.
    #[test]
    fn a_far_out_view_does_not_decide_the_model() {
        let mut scores = [
            score(
                LensModel::Pinhole5,
                0.091,
                &[
                    1.664, 0.072, 0.082, 0.074, 0.088, 0.067, 0.145, 0.092, 0.195, 0.135,
                ],
            ),
            score(
                LensModel::Fisheye,
                0.071,
                &[
                    0.181, 0.075, 0.122, 0.046, 0.057, 0.086, 0.081, 0.066, 0.085, 0.13,
                ],
            ),
            score(
                LensModel::Rational,
                0.054,
                &[
                    9.552, 0.058, 0.045, 0.045, 0.049, 0.058, 0.08, 0.037, 0.038, 0.047,
                ],
            ),
        ];
        mark_chosen(&mut scores);
        let chosen = scores.iter().find(|s| s.chosen).map(|s| s.model);
        assert_eq!(chosen, Some(LensModel::Rational));
        let best = best_held_out_px(&scores);
        assert!((best - 0.048).abs() < 1e-9, "{best}");
        assert!(!scores[0].fits_as_well(&scores) && !scores[1].fits_as_well(&scores));
        assert!(scores[2].fits_clearly_better_than(0.071));
        assert!(!scores[1].fits_clearly_better_than(0.074));
    }

    /// The held-out errors of a pinhole lens, 8 views of `synth calib --seed 1` at 640x360:
    /// one view (0.057 against 0.035 px) puts the fisheye's median 15 % under pinhole5's,
    /// every other view within 4 %; auto chose the fisheye, its cx, cy 1.2 and 1.6 px off
    /// with σ 0.5 (pinhole5: 0.4 and 0.2 px off with σ 0.9).
    #[test]
    fn one_view_does_not_break_a_near_tie_for_the_more_complex_model() {
        let score = |model, v: &[f64]| score(model, 0.054, v);
        let mut scores = [
            score(
                LensModel::Pinhole5,
                &[
                    0.0361, 0.0527, 0.0661, 0.0362, 0.0986, 0.0511, 0.0566, 0.034,
                ],
            ),
            score(
                LensModel::Fisheye,
                &[0.0366, 0.055, 0.0661, 0.0368, 0.0987, 0.051, 0.0353, 0.0346],
            ),
            score(
                LensModel::Rational,
                &[
                    0.0383, 0.0534, 0.0661, 0.0363, 0.0987, 0.051, 0.0596, 0.0339,
                ],
            ),
        ];
        assert!(scores[0].held_out_median_px.unwrap() > 1.15 * best_held_out_px(&scores));
        mark_chosen(&mut scores);
        let chosen = scores.iter().find(|s| s.chosen).map(|s| s.model);
        assert_eq!(chosen, Some(LensModel::Pinhole5));
    }
}
