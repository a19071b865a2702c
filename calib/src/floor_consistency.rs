//! Whether the floor views fit the camera the hand-held views calibrated. Through another
//! focal length (the zoom or focus changed between the sessions, or another unit of the same
//! resolution) each floor board still fits well alone, as solvePnP trades the focal length
//! for the board's depth and tilt; but the boards then sit at depths and tilts no one floor
//! has, so held together on one plane their corners no longer reproject. The views' shared
//! constraint is what tells: the rise in the reprojection error from each board alone to all
//! held on the floor, against what the corners' noise explains. The intrinsics are not
//! taken as exact: few hand-held views, or views all tilted alike, leave them loose enough
//! to misplace good floor boards, so they may move as far as their covariance allows.

use nalgebra::DMatrix;

use crate::floor::FloorBoards;
use crate::uncertainty::{residuals, view_jacobians};
use crate::{BoardToCamera, CalibError, CameraModel, FloorPlane, Observation};

/// One floor board's reprojection: its number of corners and the sums of squared residuals,
/// pixels², located alone and held on the fitted floor.
struct BoardFit {
    corners: usize,
    alone_ss: f64,
    held_ss: f64,
}

impl BoardFit {
    /// The board's corner noise per coordinate, pixels²: its own scatter about its pose, or
    /// the hand-held views' (`hand_var_px2`) when larger. Judged against the board's own
    /// scatter, a board whose corners the pixel grid pulls (its edges along the grid: 0.13 px
    /// where the hand-held views fit to 0.05 px) is not taken for a misfit.
    fn noise_var_px2(&self, hand_var_px2: f64) -> f64 {
        let dof = (2 * self.corners).saturating_sub(6).max(1) as f64;
        (self.alone_ss / dof).max(hand_var_px2)
    }
}

fn sum_sq(r: &[f64]) -> (usize, f64) {
    let ok: Vec<f64> = r.iter().copied().filter(|v| v.is_finite()).collect();
    (ok.len() / 2, ok.iter().map(|v| v * v).sum())
}

fn board_fits(camera: &CameraModel, boards: &FloorBoards, p: &[f64]) -> Vec<BoardFit> {
    let floor = boards.floor(p).0;
    boards
        .views
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let ss = |pose| {
                let o = Observation {
                    pose: BoardToCamera(pose),
                    object: &v.object_points,
                    image: &v.corners,
                };
                sum_sq(&residuals(camera, &pose, &o))
            };
            let (corners, alone_ss) = ss(boards.pnp[k].0);
            let (_, held_ss) = ss(floor * boards.board_to_floor(p, k));
            BoardFit {
                corners,
                alone_ss,
                held_ss,
            }
        })
        .collect()
}

/// The upper 99.9 % point of a χ² with `dof` degrees of freedom (Wilson–Hilferty).
fn chi2_999(dof: f64) -> f64 {
    let a = 2.0 / (9.0 * dof);
    dof * (1.0 - a + 3.09 * a.sqrt()).powi(3)
}

/// How far beyond the 99.9 % point of χ² the rise must go to refuse the floor views. The
/// figures below are of the rise with the intrinsics held; free under their covariance
/// ([`rise`]), 63 clean sets (seeds 1–4 at 640x360 and 1280x720, 3, 4 or 10 hand-held views,
/// 6 floor views) rose to 0.06–0.22 of this bound, and floor views at 80° for 70° behind 6
/// hand-held views (seeds 1–5 at 640x360) to 1.5–3.7 times it. Corners
/// the pixel grid pulls are not independent noise: over 18 clean calibrations (`synth calib
/// --views 12`, seeds 1–3, 1280x720 and 640x360, each lens model at its usual angle) the rise
/// reached 0.13–0.48 of that point, and 0.99 once (640x360 pinhole5, seed 2). Floor views
/// taken at 72° for 70° rise to 2.1 (640x360; their floor ~1 mm off, within the bound) and
/// 14.8 (1280x720); at 75°, 13 and 94 (the floor 3.4 mm off).
const BEYOND_CHANCE: f64 = 3.0;

/// The floor boards' rise from each alone to all held on one floor, in squared noise
/// (a χ² with 3 degrees of freedom per board after the first when they fit).
struct Rise {
    /// With the intrinsics free under their covariance: what they may absorb is not counted.
    chi2: f64,
    /// With the intrinsics held as calibrated.
    chi2_intrinsics_held: f64,
    /// What the intrinsics' uncertainty alone is expected to add to the rise with them held
    /// (each board's residual noise adds one per degree of freedom).
    intrinsics_expected: f64,
}

/// Rows of `blocks` one under another.
fn stack(blocks: &[DMatrix<f64>], cols: usize) -> DMatrix<f64> {
    let rows = blocks.iter().map(DMatrix::nrows).sum();
    let mut m = DMatrix::zeros(rows, cols);
    let mut at = 0;
    for b in blocks {
        m.view_mut((at, 0), b.shape()).copy_from(b);
        at += b.nrows();
    }
    m
}

/// `x` less its projection on the columns of `j` (least squares), or None when `j` does not
/// have full column rank.
fn off_columns(j: &DMatrix<f64>, x: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let inv = (j.transpose() * j).try_inverse()?;
    Some(x - j * (inv * (j.transpose() * x)))
}

/// A square root `L` of the covariance `c` (`c` = `L Lᵀ`), its negative eigenvalues (round-off)
/// taken as zero; None when `c` is not finite.
fn covariance_root(c: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    if !c.iter().all(|v| v.is_finite()) {
        return None;
    }
    let e = c.clone().symmetric_eigen();
    let roots = e.eigenvalues.map(|l| l.max(0.0).sqrt());
    Some(e.eigenvectors * DMatrix::from_diagonal(&roots))
}

/// The rise of the floor `boards` (fits `fits`) held at floor parameters `p`, with `camera`'s
/// intrinsics of `covariance` free under it. Linearised: with the boards' weighted residuals
/// z, the rise with the intrinsics held is |v|², v = Q z, Q the projection onto what the
/// boards' own poses fit and the floor does not. An error δ of the intrinsics moves z by
/// Jθ δ and v by A u, A = Q Jθ L (δ = L u, u of unit covariance); the rise that remains
/// when the intrinsics may move as far as they are known, min over u of |v − A u|² + |u|², is
/// |v|² − vᵀA (I + AᵀA)⁻¹ Aᵀv, again a χ² of the same degrees of freedom.
fn rise(
    camera: &CameraModel,
    covariance: &DMatrix<f64>,
    boards: &FloorBoards,
    p: &[f64],
    fits: &[BoardFit],
    hand_var_px2: f64,
) -> Rise {
    let held = boards.board_residuals_px(camera, p);
    let weights: Vec<f64> = fits
        .iter()
        .map(|f| 1.0 / f.noise_var_px2(hand_var_px2).sqrt())
        .collect();
    let n_theta = camera.parameters().len();
    // Per board: the weighted difference held minus alone, the intrinsics' Jacobian, and that
    // Jacobian less what the board's own pose absorbs. A corner behind the camera has no row.
    let (mut v, mut jt, mut jt_alone) = (vec![], vec![], vec![]);
    let mut finite = vec![];
    for (k, view) in boards.views.iter().enumerate() {
        let o = Observation {
            pose: boards.pnp[k],
            object: &view.object_points,
            image: &view.corners,
        };
        let alone = residuals(camera, &o.pose.0, &o);
        let ok: Vec<bool> = alone
            .iter()
            .zip(&held[k])
            .map(|(a, h)| a.is_finite() && h.is_finite())
            .collect();
        let (ji, jpose) = view_jacobians(camera, &o);
        let mask = |m: DMatrix<f64>| {
            DMatrix::from_fn(m.nrows(), m.ncols(), |r, c| {
                if ok[r] && m[(r, c)].is_finite() {
                    m[(r, c)] * weights[k]
                } else {
                    0.0
                }
            })
        };
        let (ji, jpose) = (mask(ji), mask(jpose));
        let free = off_columns(&jpose, &ji).unwrap_or_else(|| ji.clone());
        v.extend(alone.iter().zip(&held[k]).zip(&ok).map(|((a, h), &ok)| {
            if ok {
                (h - a) * weights[k]
            } else {
                0.0
            }
        }));
        jt.push(ji);
        jt_alone.push(free);
        finite.extend(ok.into_iter().map(move |ok| (ok, k)));
    }
    let v = nalgebra::DVector::from_vec(v);
    let chi2_held = v.norm_squared();
    let (jt, jt_alone) = (stack(&jt, n_theta), stack(&jt_alone, n_theta));
    // The floor's Jacobian in its parameters, weighted as the rows above.
    let h = 1e-7;
    let mut jfloor = DMatrix::zeros(v.len(), p.len());
    for d in 0..p.len() {
        let (mut a, mut b) = (p.to_vec(), p.to_vec());
        a[d] += h;
        b[d] -= h;
        let (ra, rb) = (
            boards.board_residuals_px(camera, &a).concat(),
            boards.board_residuals_px(camera, &b).concat(),
        );
        for (r, &(ok, k)) in finite.iter().enumerate() {
            let dr = (ra[r] - rb[r]) / (2.0 * h) * weights[k];
            jfloor[(r, d)] = if ok && dr.is_finite() { dr } else { 0.0 };
        }
    }
    let (Some(root), Some(jt_held)) = (covariance_root(covariance), off_columns(&jfloor, &jt))
    else {
        return Rise {
            chi2: chi2_held,
            chi2_intrinsics_held: chi2_held,
            intrinsics_expected: 0.0,
        };
    };
    let a = (jt_held - jt_alone) * root;
    let b = a.transpose() * &v;
    let m = DMatrix::identity(n_theta, n_theta) + a.transpose() * &a;
    let absorbed = m.cholesky().map_or(0.0, |c| b.dot(&c.solve(&b)));
    Rise {
        chi2: (chi2_held - absorbed).max(0.0),
        chi2_intrinsics_held: chi2_held,
        intrinsics_expected: a.norm_squared(),
    }
}

/// The intrinsics are loose when their uncertainty alone is expected to raise the floor
/// boards' rise (intrinsics held) this many times as much as the corners' noise does. Four
/// hand-held views of `synth calib` at 640x360 gave 5–40 times (a focal length known to
/// 2–3 %), ten views 1–2 times, six views 2–3 times.
const LOOSE: f64 = 4.0;

/// What the floor boards say when they fit only with the intrinsics moved within their
/// uncertainty: a zoom would pass too.
const LOOSE_ADVICE: &str = "add hand-held views with the board tilted other ways (to the left, right, top and bottom of the image, turned towards and away from the camera)";

/// Refuses floor views that do not fit `camera`, calibrated by hand-held views fitting to
/// `hand_rms_px` (RMS per corner) with intrinsics of `covariance`: the rise in the floor
/// boards' squared reprojection error, each over its noise, from each board alone (6 pose
/// numbers each) to all held on the floor `plane` of parameters `p` (6 for the floor and 3
/// per further board), the intrinsics free as far as they are known ([`rise`]), is a χ² with
/// 3 degrees of freedom per board after the first when they fit; far beyond its 99.9 %
/// point ([`BEYOND_CHANCE`]) they do not. A warning when they fit only thanks to loose
/// intrinsics.
pub(crate) fn check_floor_fits_camera(
    camera: &CameraModel,
    covariance: &DMatrix<f64>,
    boards: &FloorBoards,
    p: &[f64],
    plane: &FloorPlane,
    hand_rms_px: f64,
) -> Result<Option<String>, CalibError> {
    let fits = board_fits(camera, boards, p);
    if fits.len() < 2 {
        return Ok(None);
    }
    let hand_var_px2 = hand_rms_px.powi(2) / 2.0;
    let rise = rise(camera, covariance, boards, p, &fits, hand_var_px2);
    let dof = 3.0 * (fits.len() - 1) as f64;
    let bound = BEYOND_CHANCE * chi2_999(dof);
    let corners = fits.iter().map(|f| f.corners).sum::<usize>().max(1) as f64;
    let rms = |ss: f64| (ss / corners).sqrt();
    let held_px = rms(fits.iter().map(|f| f.held_ss).sum());
    let alone_px = rms(fits.iter().map(|f| f.alone_ss).sum());
    let misfit = format!(
        "held on one floor, their boards' corners sit {held_px:.3} px off, where each board alone fits to {alone_px:.3} px (hand-held views: {hand_rms_px:.3} px)"
    );
    let loose = rise.intrinsics_expected > LOOSE * dof;
    if rise.chi2 <= bound {
        return Ok((loose && rise.chi2_intrinsics_held > bound).then(|| format!(
            "warning: the floor views fit the camera the hand-held views calibrated only with its focal length and centre moved within their uncertainty ({misfit}): the hand-held views leave them so loose that floor views taken at another zoom or focus would pass too; {LOOSE_ADVICE}"
        )));
    }
    let loose_first = if loose {
        format!(
            "the hand-held views leave the focal length and centre loose (their uncertainty alone would raise this misfit {:.0} times as much as the corners' noise): {LOOSE_ADVICE}, and calibrate again; if the floor views still do not fit, ",
            rise.intrinsics_expected / dof
        )
    } else {
        String::new()
    };
    Err(CalibError::Input(format!(
        "the floor views do not fit the camera the hand-held views calibrated: {misfit}, and their boards lie {:.1} mm RMS off one plane; {loose_first}were they taken at another zoom or focus, or by another camera? Take the floor views and the hand-held views with the camera as it will track, unchanged in between",
        plane.plane_rms_m * 1e3
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Wilson–Hilferty against the tabulated 99.9 % points of χ² with 3, 9 and 30 degrees.
    #[test]
    fn chi2_points() {
        for (dof, q) in [(3.0, 16.27), (9.0, 27.88), (30.0, 59.70)] {
            assert!(
                (chi2_999(dof) - q).abs() < 0.02 * q,
                "{dof}: {}",
                chi2_999(dof)
            );
        }
    }
}
