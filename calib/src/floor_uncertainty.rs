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

use nalgebra::{DMatrix, Matrix2, Point2, Vector2};
use serde::{Deserialize, Serialize};

use crate::floor::FloorBoards;
use crate::uncertainty::{steps, worst_sigma};
use crate::{BoardSpec, BoardView, CalibError, CameraModel, FloorToCamera, UncertaintyMap};

/// Rays more than this far from straight down graze the floor; such cells are not mapped
/// (walls, or the floor so far off that one pixel spans decimetres).
pub const FLOOR_SEEN_MAX_OFF_NADIR_DEG: f64 = 80.0;

/// The floor-mapping bound whose reach `odocal calibrate` reports, millimetres ...
pub const FLOOR_BOUND_MM: f64 = 2.0;
/// ... held at this many standard deviations of [`FloorUncertaintyMap`]'s σ.
pub const FLOOR_BOUND_SIGMAS: f64 = 3.0;

/// The share of the bound that lens models fitting the views alike may differ by where the
/// floor is vouched for: their difference shows how far the lens is unknown there, but the
/// true lens may lie beyond either model (on a 150° fisheye, 2.15 mm from the truth where
/// the models differed by at most 2 mm), so they must agree within half the bound.
pub const MODEL_SPREAD_SHARE: f64 = 0.5;

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
    /// When the disc ends where lens models the views could not tell apart map the floor
    /// too far apart ([`MODEL_SPREAD_SHARE`] of the bound; rather than where σ grows): the
    /// largest such difference over the floor, millimetres.
    pub model_spread_mm: Option<f64>,
}

impl FloorReach {
    /// One line for people: how far out the floor is vouched for, at [`FLOOR_BOUND_MM`] and
    /// [`FLOOR_BOUND_SIGMAS`] (the bound [`FloorUncertaintyMap::vouched_reach`] uses), and
    /// what extends it. `model_given`: the lens model was fixed with `--model`, so the
    /// models bounding the floor are ones fitting the views clearly better, not as well.
    pub fn sentence(&self, model_given: bool) -> String {
        let bound = format!("within {FLOOR_BOUND_MM} mm ({FLOOR_BOUND_SIGMAS}σ)");
        if self.whole {
            format!(
                "the whole floor the image sees is mapped {bound}: out to {:.2} m from the point under the camera ({:.0}° off the nadir)",
                self.radius_m, self.off_nadir_deg
            )
        } else if let Some(spread) = self.model_spread_mm {
            let spread = far_mm(spread, 1);
            if model_given {
                format!(
                    "floor mapped {bound} out to {:.2} m from the point under the camera ({:.0}° off the nadir); farther out a lens model that fits the views clearly better maps the floor up to {spread} away from --model's, so it cannot be vouched for there: calibrate with the better-fitting model the warning names",
                    self.radius_m, self.off_nadir_deg
                )
            } else {
                format!(
                    "floor mapped {bound} out to {:.2} m from the point under the camera ({:.0}° off the nadir); farther out the lens models that fit the views equally well map the floor up to {spread} apart, so none can be vouched for there: add hand-held views reaching the image's corners and edges, or give the lens model (--model)",
                    self.radius_m, self.off_nadir_deg
                )
            }
        } else {
            format!(
                "floor mapped {bound} out to {:.2} m from the point under the camera ({:.0}° off the nadir); farther out 1σ grows to {}: add floor views farther out and hand-held views reaching the image's edges",
                self.radius_m,
                self.off_nadir_deg,
                far_mm(self.worst_sigma_mm, 1)
            )
        }
    }
}

/// A floor distance in millimetres for people, with `decimals` places, or "more than a
/// metre": far out, where rays graze the floor (or a lens model turns over and its rays
/// never reach it), σ and the models' spread run to metres or beyond, and a figure such as
/// "49106795642.9 mm" says nothing more than that.
pub fn far_mm(mm: f64, decimals: usize) -> String {
    if mm < 1000.0 {
        format!("{mm:.decimals$} mm")
    } else {
        "more than a metre".to_string()
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
    /// Per cell, how far apart the chosen lens model and the others the held-out views
    /// could not tell from it map the floor, millimetres ([`Self::add_model_spread`]); empty
    /// when no other model fitted as well. The covariance says how well one model's
    /// parameters are known, not whether the model is the lens: where the views leave the
    /// image empty, models alike on the views part ways.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub model_spread_mm: Vec<Option<f64>>,
    /// Per cell, the floor point's covariance in the floor frame as (xx, xy, yy), square
    /// millimetres, where `sigma_mm` has a value: the ellipse whose longest axis is that σ.
    /// `track` takes a fix's calibration part along x and y from it, not the worst direction
    /// both ways, which overstated σ along the other. Empty in files written before it was
    /// kept ([`Self::covariance_at`] then falls back on the worst direction's σ).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub covariance_mm2: Vec<Option<[f64; 3]>>,
    /// Joint covariance of a small correction to the floor pose (rotation vector, then
    /// translation, in radians and metres, applied on the floor's side: `floor_to_camera ∘
    /// correction`) and of the intrinsics (`CameraModel::parameters`), from the floor boards'
    /// corner noise and the intrinsics' covariance ([`Self::floor_covariance_matrix`]). The
    /// map's σ describe this camera's own fixes; a floor frame shared with other cameras (an
    /// arena's, which is its first camera's) carries this covariance to every camera tied to
    /// it, far beyond this image. None in files written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor_covariance: Option<Vec<Vec<f64>>>,
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
        let boards = FloorBoards::locate(camera, floor_views, board, corner_sigma_px)?;
        let fitted = boards.fit_parameters(camera);
        Self::from_fit(camera, covariance, &boards, &fitted, cell_px)
    }

    /// The map for the floor `boards` fitted at parameters `fitted` (see [`Self::new`]).
    pub(crate) fn from_fit(
        camera: &CameraModel,
        covariance: &DMatrix<f64>,
        boards: &FloorBoards,
        fitted: &[f64],
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
        let floor = boards.floor(fitted);
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
        let hs = steps(camera);
        // The floor fit's residuals are weighted by each board's corner noise, so its
        // information matrix is JpᵀJp and the floor parameters' covariance its inverse. A change
        // of the intrinsics moves the fitted floor by the Gauss-Newton sensitivity
        // dp/dθ = -(JpᵀJp)⁻¹ JpᵀJθ, so nothing is refitted numerically.
        let np = fitted.len();
        let column = |f: &dyn Fn(f64) -> Vec<f64>, h: f64| -> Vec<f64> {
            f(h).iter()
                .zip(f(-h))
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect()
        };
        let mut jp_cols = Vec::with_capacity(np);
        for d in 0..np {
            jp_cols.push(column(
                &|h| {
                    let mut q = fitted.to_vec();
                    q[d] += h;
                    boards.weighted_residuals(camera, &q)
                },
                1e-7,
            ));
        }
        let mut jt_cols = Vec::with_capacity(n);
        for (i, h) in hs.iter().enumerate() {
            jt_cols.push(column(
                &|h| {
                    let mut t = p0.clone();
                    t[i] += h;
                    boards.weighted_residuals(&camera.with_parameters(&t), fitted)
                },
                *h,
            ));
        }
        let m = jp_cols.first().map_or(0, Vec::len);
        let jp = DMatrix::from_fn(m, np, |r, c| jp_cols[c][r]);
        let jt = DMatrix::from_fn(m, n, |r, c| jt_cols[c][r]);
        if !jp.iter().chain(jt.iter()).all(|v| v.is_finite()) {
            return Err(CalibError::Input(
                "a floor board's corners cannot be projected: is every floor board in front of the camera?".into(),
            ));
        }
        let Some(info_inv) = (jp.transpose() * &jp).try_inverse() else {
            return Err(CalibError::Input(
                "the floor boards do not fix the floor plane (are they all the same view?)".into(),
            ));
        };
        let dp_dtheta = -(&info_inv * jp.transpose() * &jt);
        let floor_cov = info_inv.view((0, 0), (6, 6)).into_owned();
        let dfloor_dtheta = dp_dtheta.rows(0, 6).into_owned();
        // The floor pose's joint covariance with the intrinsics: its own (the boards' corner
        // noise) plus what the intrinsics' error moves it by. The parameters' correction is
        // applied after the fitted one (`FloorBoards::floor`), which to first order is the
        // same as a correction of the fitted pose on its floor side.
        let moved_by_intrinsics = &dfloor_dtheta * covariance;
        let mut joint = DMatrix::<f64>::zeros(6 + n, 6 + n);
        joint
            .view_mut((0, 0), (6, 6))
            .copy_from(&(&floor_cov + &moved_by_intrinsics * dfloor_dtheta.transpose()));
        joint
            .view_mut((0, 6), (6, n))
            .copy_from(&moved_by_intrinsics);
        joint
            .view_mut((6, 0), (n, 6))
            .copy_from(&moved_by_intrinsics.transpose());
        joint.view_mut((6, 6), (n, n)).copy_from(covariance);
        // Written symmetric to the last bit: the products above leave it so to only 1e-8.
        let joint = (&joint + joint.transpose()) * 0.5;
        let mut cov = vec![Matrix2::<f64>::zeros(); pixels.len()];
        for (k, pix) in pixels.iter().enumerate() {
            if !seen[k] {
                continue;
            }
            // d(floor point)/d(floor pose), and d(floor point)/d(intrinsics) with the floor held.
            let mut jf = DMatrix::<f64>::zeros(2, 6);
            for d in 0..6 {
                let h = 1e-7;
                let (mut a, mut b) = (fitted.to_vec(), fitted.to_vec());
                a[d] += h;
                b[d] -= h;
                if let Some(dd) =
                    difference(camera, &boards.floor(&a), camera, &boards.floor(&b), pix)
                {
                    jf[(0, d)] = dd.x / (2.0 * h);
                    jf[(1, d)] = dd.y / (2.0 * h);
                }
            }
            let mut ji = DMatrix::<f64>::zeros(2, n);
            for (i, h) in hs.iter().enumerate() {
                let (mut plus, mut minus) = (p0.clone(), p0.clone());
                plus[i] += h;
                minus[i] -= h;
                let (cp, cm) = (
                    camera.with_parameters(&plus),
                    camera.with_parameters(&minus),
                );
                if let Some(d) = difference(&cp, &floor, &cm, &floor, pix) {
                    ji[(0, i)] = d.x / (2.0 * h);
                    ji[(1, i)] = d.y / (2.0 * h);
                }
            }
            let j_int = ji + &jf * &dfloor_dtheta;
            let s = &jf * &floor_cov * jf.transpose() + &j_int * covariance * j_int.transpose();
            cov[k] = Matrix2::new(s[(0, 0)], s[(0, 1)], s[(1, 0)], s[(1, 1)]);
        }

        let sigma_mm: Vec<Option<f64>> = cov
            .iter()
            .zip(&seen)
            .map(|(c, &s)| {
                let worst = worst_sigma(c);
                (s && worst.is_finite()).then_some(worst * 1000.0)
            })
            .collect();
        let covariance_mm2 = cov
            .iter()
            .zip(&sigma_mm)
            .map(|(c, s)| s.map(|_| [c[(0, 0)] * 1e6, c[(0, 1)] * 1e6, c[(1, 1)] * 1e6]))
            .collect();
        Ok(Self {
            cell_px,
            cols,
            rows,
            sigma_mm,
            floor_boards_px: boards
                .views
                .iter()
                .map(|v| v.corners.iter().map(|p| [p.x, p.y]).collect())
                .collect(),
            model_spread_mm: Vec::new(),
            covariance_mm2,
            floor_covariance: Some(
                joint
                    .row_iter()
                    .map(|r| r.iter().copied().collect())
                    .collect(),
            ),
        })
    }

    /// [`Self::floor_covariance`] as a matrix, if the map has one that is square.
    pub fn floor_covariance_matrix(&self) -> Option<DMatrix<f64>> {
        let rows = self.floor_covariance.as_ref()?;
        let n = rows.len();
        if rows.iter().any(|r| r.len() != n) {
            return None;
        }
        Some(DMatrix::from_fn(n, n, |i, j| rows[i][j]))
    }

    /// The index of the cell holding `pixel` (None off the map).
    fn cell_of(&self, pixel: &Point2<f64>) -> Option<usize> {
        if pixel.x < 0.0 || pixel.y < 0.0 {
            return None;
        }
        let c = (pixel.x / self.cell_px as f64) as u32;
        let r = (pixel.y / self.cell_px as f64) as u32;
        (c < self.cols && r < self.rows).then_some((r * self.cols + c) as usize)
    }

    /// The σ of the cell holding `pixel`, millimetres (None off the map or off the floor).
    pub fn at(&self, pixel: &Point2<f64>) -> Option<f64> {
        self.sigma_mm.get(self.cell_of(pixel)?).copied().flatten()
    }

    /// The covariance of the floor point seen in the cell holding `pixel`, in the floor
    /// frame, square millimetres: [`Self::covariance_mm2`]'s, or where a file has none, the
    /// worst direction's σ in every direction (None off the map or off the floor).
    pub fn covariance_at(&self, pixel: &Point2<f64>) -> Option<Matrix2<f64>> {
        let k = self.cell_of(pixel)?;
        let sigma = self.sigma_mm.get(k).copied().flatten()?;
        Some(match self.covariance_mm2.get(k).copied().flatten() {
            Some([xx, xy, yy]) => Matrix2::new(xx, xy, xy, yy),
            None => Matrix2::identity() * sigma * sigma,
        })
    }

    /// Whether lens models that fit the views alike map the floor at `pixel` too far apart
    /// for the bound odocal vouches for ([`MODEL_SPREAD_SHARE`] of [`FLOOR_BOUND_MM`]).
    pub fn models_part_at(&self, pixel: &Point2<f64>) -> bool {
        self.cell_of(pixel)
            .and_then(|k| self.model_spread_mm.get(k).copied().flatten())
            .is_some_and(|d| d > MODEL_SPREAD_SHARE * FLOOR_BOUND_MM)
    }

    /// Records, per cell that sees the floor, the largest distance between the floor point
    /// `camera` with `floor` maps it to and the one each of `others` (another lens model's
    /// calibration of the same views, with its own floor) maps it to, millimetres.
    pub fn add_model_spread(
        &mut self,
        camera: &CameraModel,
        floor: &FloorToCamera,
        others: &[(CameraModel, FloorToCamera)],
    ) {
        if others.is_empty() {
            return;
        }
        let mut spread = vec![None; self.sigma_mm.len()];
        for r in 0..self.rows {
            for c in 0..self.cols {
                let k = (r * self.cols + c) as usize;
                if !matches!(self.sigma_mm.get(k), Some(Some(_))) {
                    continue;
                }
                let pix = UncertaintyMap::centre(camera, self.cell_px, c, r);
                let worst = others
                    .iter()
                    .map(|(cam, fl)| {
                        difference(camera, floor, cam, fl, &pix).map_or(f64::INFINITY, |d| d.norm())
                    })
                    .fold(0.0f64, f64::max);
                spread[k] = Some(1000.0 * worst);
            }
        }
        self.model_spread_mm = spread;
    }

    /// How far out from the point under the camera the floor is mapped with at most
    /// `sigma_mm` of uncertainty (1σ): the disc around that point in which every mapped cell
    /// stays within it, up to the nearest cell that does not (or, when none exceeds it, out
    /// to the farthest mapped cell). A cell where lens models that fit the views alike map
    /// the floor more than [`MODEL_SPREAD_SHARE`] of [`FLOOR_BOUND_SIGMAS`] σ apart counts as
    /// over it too. `camera`
    /// and `floor` are the calibration's own.
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
        // The nearest cell over by σ, and by the models' spread, with the largest spread.
        let (mut nearest_sigma_over, mut worst_spread) = (f64::INFINITY, 0.0f64);
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
                    nearest_sigma_over = nearest_sigma_over.min(d);
                }
                let spread = self
                    .model_spread_mm
                    .get((r * self.cols + c) as usize)
                    .copied()
                    .flatten()
                    .unwrap_or(0.0);
                worst_spread = worst_spread.max(spread);
                if spread > MODEL_SPREAD_SHARE * FLOOR_BOUND_SIGMAS * sigma_mm {
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
            model_spread_mm: (nearest_over < nearest_sigma_over).then_some(worst_spread),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The covariance behind a cell's σ where the map has it; the worst direction's σ both
    /// ways where a file from before it was kept has not; nothing off the floor.
    #[test]
    fn a_cell_gives_its_covariance_or_its_worst_sigma_both_ways() {
        let mut map = FloorUncertaintyMap {
            cell_px: 20,
            cols: 2,
            rows: 1,
            sigma_mm: vec![Some(0.5), None],
            floor_boards_px: vec![],
            model_spread_mm: vec![],
            covariance_mm2: vec![],
            floor_covariance: None,
        };
        let (on, off) = (Point2::new(5.0, 5.0), Point2::new(25.0, 5.0));
        assert_eq!(
            map.covariance_at(&on),
            Some(Matrix2::new(0.25, 0.0, 0.0, 0.25))
        );
        assert_eq!(map.covariance_at(&off), None);
        map.covariance_mm2 = vec![Some([0.25, 0.01, 0.04]), None];
        assert_eq!(
            map.covariance_at(&on),
            Some(Matrix2::new(0.25, 0.01, 0.01, 0.04))
        );
        assert_eq!(map.covariance_at(&off), None);
    }

    /// Where models bound the floor, the sentence names the kind of model that does, and a
    /// spread of metres (rays grazing the floor) is not printed as "102643.5 mm".
    #[test]
    fn the_reach_names_what_bounds_it() {
        let reach = FloorReach {
            radius_m: 0.46,
            off_nadir_deg: 10.0,
            whole: false,
            worst_sigma_mm: 0.3,
            model_spread_mm: Some(102_643.5),
        };
        let given = reach.sentence(true);
        assert!(
            given.contains("a lens model that fits the views clearly better maps the floor up to more than a metre away from --model's")
                && !given.contains("give the lens model"),
            "{given}"
        );
        let auto = FloorReach {
            model_spread_mm: Some(1.34),
            ..reach
        }
        .sentence(false);
        assert!(
            auto.contains(
                "the lens models that fit the views equally well map the floor up to 1.3 mm apart"
            ) && auto.ends_with("or give the lens model (--model)"),
            "{auto}"
        );
    }

    /// Beyond the vouched floor of a 125° rational lens the model turns over and σ there ran
    /// to 49106795642.9 mm; that is said as what it means.
    #[test]
    fn a_sigma_of_metres_beyond_the_reach_is_said_in_words() {
        let reach = FloorReach {
            radius_m: 1.2,
            off_nadir_deg: 29.0,
            whole: false,
            worst_sigma_mm: 49_106_795_642.9,
            model_spread_mm: None,
        };
        let said = reach.sentence(false);
        assert!(
            said.contains("farther out 1σ grows to more than a metre: add floor views")
                && !said.contains("49106795642"),
            "{said}"
        );
        let near = FloorReach {
            worst_sigma_mm: 36.12,
            ..reach
        }
        .sentence(false);
        assert!(near.contains("farther out 1σ grows to 36.1 mm:"), "{near}");
        assert_eq!(far_mm(999.94, 3), "999.940 mm");
        assert_eq!(far_mm(f64::INFINITY, 3), "more than a metre");
    }
}
