//! Whether the floor views fit the camera the hand-held views calibrated. Through another
//! focal length (the zoom or focus changed between the sessions, or another unit of the same
//! resolution) each floor board still fits well alone, as solvePnP trades the focal length
//! for the board's depth and tilt; but the boards then sit at depths and tilts no one floor
//! has, so held together on one plane their corners no longer reproject. The views' shared
//! constraint is what tells: the rise in the reprojection error from each board alone to all
//! held on the floor, against what the corners' noise explains.

use crate::floor::FloorBoards;
use crate::uncertainty::residuals;
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

/// How far beyond the 99.9 % point of χ² the rise must go to refuse the floor views. Corners
/// the pixel grid pulls are not independent noise: over 18 clean calibrations (`synth calib
/// --views 12`, seeds 1–3, 1280x720 and 640x360, each lens model at its usual angle) the rise
/// reached 0.13–0.48 of that point, and 0.99 once (640x360 pinhole5, seed 2). Floor views
/// taken at 72° for 70° rise to 2.1 (640x360; their floor ~1 mm off, within the bound) and
/// 14.8 (1280x720); at 75°, 13 and 94 (the floor 3.4 mm off).
const BEYOND_CHANCE: f64 = 3.0;

/// Refuses floor views that do not fit `camera`, calibrated by hand-held views fitting to
/// `hand_rms_px` (RMS per corner): the rise in the floor boards' squared reprojection error,
/// each over its noise, from each board alone (6 pose numbers each) to all held on the floor
/// `plane` of parameters `p` (6 for the floor and 3 per further board) is a χ² with 3 degrees
/// of freedom per board after the first when they fit; far beyond its 99.9 % point
/// ([`BEYOND_CHANCE`]) they do not.
pub(crate) fn check_floor_fits_camera(
    camera: &CameraModel,
    boards: &FloorBoards,
    p: &[f64],
    plane: &FloorPlane,
    hand_rms_px: f64,
) -> Result<(), CalibError> {
    let fits = board_fits(camera, boards, p);
    if fits.len() < 2 {
        return Ok(());
    }
    let hand_var_px2 = hand_rms_px.powi(2) / 2.0;
    let rise: f64 = fits
        .iter()
        .map(|f| (f.held_ss - f.alone_ss).max(0.0) / f.noise_var_px2(hand_var_px2))
        .sum();
    let dof = 3.0 * (fits.len() - 1) as f64;
    let corners = fits.iter().map(|f| f.corners).sum::<usize>().max(1) as f64;
    let rms = |ss: f64| (ss / corners).sqrt();
    let held_px = rms(fits.iter().map(|f| f.held_ss).sum());
    let alone_px = rms(fits.iter().map(|f| f.alone_ss).sum());
    if rise <= BEYOND_CHANCE * chi2_999(dof) {
        return Ok(());
    }
    Err(CalibError::Input(format!(
        "the floor views do not fit the camera the hand-held views calibrated: held on one floor, their boards' corners sit {held_px:.3} px off, where each board alone fits to {alone_px:.3} px (hand-held views: {hand_rms_px:.3} px), and their boards lie {:.1} mm RMS off one plane; were they taken at another zoom or focus, or by another camera? Take the floor views and the hand-held views with the camera as it will track, unchanged in between",
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
