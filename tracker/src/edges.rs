//! Sub-pixel refinement of a tag's corners from the grey levels along its four sides.
//!
//! The quad fit of the AprilTag C library places corners to about a tenth of a pixel, with an
//! error that depends on where the edges fall on the pixel grid. On a 35-pixel tag (8 cm seen
//! from 2.2 m) that is 1.5–5 mrad of heading at a given pose, and the error does not average
//! away over frames at rest; a 1.5 m run turns it into several millimetres at its end. Here the
//! outer edges of the four sides (black square against the tag's white border) are fitted to
//! the pixels around them, some 500 in all: a pixel averages a straight edge over its area, so
//! its grey level ramps linearly from dark to light across the edge over the pixel's extent
//! along the edge's normal (widened by optical blur, one parameter shared by the four sides).
//! Edge angles and offsets, the two levels and the blur are found by Levenberg–Marquardt; the
//! corners are the intersections of the fitted lines.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{Dyn, Owned, Point2, Vector2, U11};

use crate::source::GrayFrame;

/// Pixels farther than this from the detected side are not used, pixels.
const REACH_PX: f64 = 2.5;
/// Fraction of each side left out at both ends (the neighbouring side's edge is there).
const END_FRACTION: f64 = 0.12;
/// Fraction of each side's length whose pixels are fitted.
pub(crate) const FITTED_FRACTION: f64 = 1.0 - 2.0 * END_FRACTION;
/// Pixels farther than this from the detected line are grouped in the first fit, pixels (a
/// sharp edge's ramp is at most 0.71 px either side of its line; on the default scene's video
/// every fit stays exact, with 220 rows instead of 540).
const GROUP_BEYOND_PX: f64 = 1.0;
/// A refined corner farther than this from the detected one means the fit went astray, pixels.
const MAX_SHIFT_PX: f64 = 1.5;

/// The pixels along the four sides, each in coordinates centred on its side's midpoint.
///
/// Parameters: per side the normal angle φ (towards the white border) and offset ρ, then the
/// dark and light levels and the log blur u, shared by the four sides (one tag, one focus).
struct EdgeFit {
    side: Vec<usize>,
    q: Vec<Vector2<f64>>,
    grey: Vec<f64>,
    /// The residual row of each pixel: its own, or its group's (see [`EdgeFit::group_flat`]).
    row: Vec<usize>,
    /// Each row's weight, 1/√(pixels in it).
    row_weight: Vec<f64>,
    /// Whether each pixel was grouped on the light side of its line.
    grouped_light: Vec<bool>,
    p: Params,
    /// Per side (cos φ, sin φ, ramp width W) at `p`: set once per parameter update, not per
    /// pixel (the sines and cosines were a sixth of the tracker's time).
    sides: [(f64, f64, f64); 4],
}

type Params = nalgebra::OVector<f64, U11>;
const LO: usize = 8;
const HI: usize = 9;
const BLUR: usize = 10;
/// Weight of the prior "no blur beyond the pixel's own extent", grey levels per unit of u.
///
/// A sharp edge leaves one row of partial pixels, which cannot tell the blur from the edge's
/// position within that row; a blurred edge spreads over several and overrides the prior.
const BLUR_PRIOR: f64 = 30.0;

impl EdgeFit {
    /// One residual row per pixel.
    fn ungrouped(&mut self) {
        self.row = (0..self.q.len()).collect();
        self.row_weight = vec![1.0; self.q.len()];
    }

    /// Pixels farther than `core_px` from their side's line at the current parameters share
    /// one row per side and level (dark or light): the row holds the sum of their residuals
    /// and Jacobian rows over √(count). While they stay on their level, each of those pixels
    /// has the same Jacobian row (1 under that level, 0 elsewhere), so the grouped problem has
    /// the per-pixel problem's gradient and Gauss–Newton matrix and the same optimum, with a
    /// QR well under half the size. [`EdgeFit::groups_exact`] says whether they stayed.
    fn group_flat(&mut self, core_px: f64) {
        let mut group_row = [[usize::MAX; 2]; 4];
        self.row.clear();
        self.grouped_light.clear();
        let mut count: Vec<usize> = Vec::new();
        for k in 0..self.q.len() {
            let d = self.model(k).1;
            let row = if d.abs() <= core_px {
                count.push(1);
                count.len() - 1
            } else {
                let slot = &mut group_row[self.side[k]][usize::from(d > 0.0)];
                if *slot == usize::MAX {
                    count.push(0);
                    *slot = count.len() - 1;
                }
                count[*slot] += 1;
                *slot
            };
            self.row.push(row);
            self.grouped_light.push(d > 0.0);
        }
        self.row_weight = count.iter().map(|&c| 1.0 / (c as f64).sqrt()).collect();
    }

    /// Whether every grouped pixel is on its flat level at the current parameters (so the
    /// grouped fit is the per-pixel fit).
    fn groups_exact(&self) -> bool {
        (0..self.q.len()).all(|k| {
            self.row_weight[self.row[k]] == 1.0 || {
                let (_, d, dd, _, _, _) = self.model(k);
                dd == 0.0 && (d > 0.0) == self.grouped_light[k]
            }
        })
    }

    /// Grey level of pixel k and its derivatives by (signed distance, dark, light, blur).
    ///
    /// A pixel averages a straight edge over its area: across the edge the grey level ramps
    /// linearly over the pixel's extent along the normal, W0 = |cos φ| + |sin φ|, widened by
    /// the optics to W = W0 e^u.
    fn model(&self, k: usize) -> (f64, f64, f64, f64, f64, f64) {
        let i = self.side[k];
        let rho = self.p[4 + i];
        let (lo, hi) = (self.p[LO], self.p[HI]);
        let (c, s, w) = self.sides[i];
        let q = self.q[k];
        let d = c * q.x + s * q.y - rho;
        let z = 0.5 + d / w;
        if z <= 0.0 {
            (lo, d, 0.0, 1.0, 0.0, 0.0)
        } else if z >= 1.0 {
            (hi, d, 0.0, 0.0, 1.0, 0.0)
        } else {
            let slope = (hi - lo) / w;
            (lo + (hi - lo) * z, d, slope, 1.0 - z, z, -slope * d)
        }
    }
}

impl LeastSquaresProblem<f64, Dyn, U11> for EdgeFit {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, U11>;
    type ParameterStorage = Owned<f64, U11>;

    fn set_params(&mut self, p: &Params) {
        self.p = *p;
        let blur = p[BLUR].exp();
        for (i, side) in self.sides.iter_mut().enumerate() {
            let (s, c) = p[i].sin_cos();
            *side = (c, s, (c.abs() + s.abs()) * blur);
        }
    }

    fn params(&self) -> Params {
        self.p
    }

    fn residuals(&self) -> Option<nalgebra::DVector<f64>> {
        let m = self.row_weight.len();
        let mut r = nalgebra::DVector::zeros(m + 1);
        for k in 0..self.q.len() {
            let row = self.row[k];
            r[row] += (self.model(k).0 - self.grey[k]) * self.row_weight[row];
        }
        r[m] = BLUR_PRIOR * self.p[BLUR];
        Some(r)
    }

    fn jacobian(&self) -> Option<nalgebra::OMatrix<f64, Dyn, U11>> {
        let m = self.row_weight.len();
        let mut j = nalgebra::OMatrix::<f64, Dyn, U11>::zeros(m + 1);
        j[(m, BLUR)] = BLUR_PRIOR;
        for k in 0..self.q.len() {
            let i = self.side[k];
            let row = self.row[k];
            let w = self.row_weight[row];
            let (_, _, dd, dlo, dhi, du) = self.model(k);
            let (c, s, _) = self.sides[i];
            let q = self.q[k];
            // The ramp width's own dependence on φ is left out: it is second order.
            j[(row, i)] += w * dd * (-s * q.x + c * q.y);
            j[(row, 4 + i)] -= w * dd;
            j[(row, LO)] += w * dlo;
            j[(row, HI)] += w * dhi;
            j[(row, BLUR)] += w * du;
        }
        Some(j)
    }
}

/// Collects the pixels within reach of the side from `a` to `b` (away from its ends) into
/// `fit` as side `i`; returns the side's midpoint and initial normal angle.
fn collect_side(
    frame: &GrayFrame,
    fit: &mut EdgeFit,
    i: usize,
    a: Point2<f64>,
    b: Point2<f64>,
    inside: Point2<f64>,
) -> Option<(Point2<f64>, f64)> {
    let len = (b - a).norm();
    if len < 8.0 {
        return None;
    }
    let dir = (b - a) / len;
    let mid = nalgebra::center(&a, &b);
    let mut n = Vector2::new(-dir.y, dir.x);
    if n.dot(&(mid - inside)) < 0.0 {
        n = -n;
    }
    let (w, h) = (frame.width as i64, frame.height as i64);
    let lo_x = (a.x.min(b.x) - REACH_PX).floor() as i64;
    let hi_x = (a.x.max(b.x) + REACH_PX).ceil() as i64;
    let lo_y = (a.y.min(b.y) - REACH_PX).floor() as i64;
    let hi_y = (a.y.max(b.y) + REACH_PX).ceil() as i64;
    if lo_x < 0 || lo_y < 0 || hi_x >= w || hi_y >= h {
        return None;
    }
    let before = fit.q.len();
    for y in lo_y..=hi_y {
        for x in lo_x..=hi_x {
            let r = Vector2::new(x as f64, y as f64) - mid.coords;
            let along = r.dot(&dir) / len + 0.5;
            if n.dot(&r).abs() <= REACH_PX && (END_FRACTION..=1.0 - END_FRACTION).contains(&along) {
                fit.side.push(i);
                fit.q.push(r);
                fit.grey.push(frame.data[(y * w + x) as usize] as f64);
            }
        }
    }
    (fit.q.len() - before >= 10).then_some((mid, n.y.atan2(n.x)))
}

/// The tag's corners refined from its four sides, or `None` when a side cannot be fitted (too
/// small, at the image border, too little contrast) or the fit moved a corner implausibly far.
pub(crate) fn refine_corners(
    frame: &GrayFrame,
    corners: &[Point2<f64>; 4],
) -> Option<[Point2<f64>; 4]> {
    let inside = crate::detect::quad_centre(corners);
    let mut fit = EdgeFit {
        side: Vec::new(),
        q: Vec::new(),
        grey: Vec::new(),
        row: Vec::new(),
        row_weight: Vec::new(),
        grouped_light: Vec::new(),
        p: Params::zeros(),
        sides: [(1.0, 0.0, 1.0); 4],
    };
    let mut mids = [Point2::origin(); 4];
    for i in 0..4 {
        let (mid, phi) =
            collect_side(frame, &mut fit, i, corners[i], corners[(i + 1) % 4], inside)?;
        mids[i] = mid;
        fit.p[i] = phi;
    }
    let dark = fit.grey.iter().copied().fold(f64::INFINITY, f64::min);
    let light = fit.grey.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if light - dark < 20.0 {
        return None;
    }
    let mut start = fit.p;
    start[LO] = dark;
    start[HI] = light;
    fit.set_params(&start);
    // Relative tolerances of 1e-6 put the poses within 2 µm and 9 µrad of a fit to 1e-10 (on
    // a default-scene video whose noise is 64 µm and 1500 µrad RMS), in 7 evaluations
    // instead of 12: the QR decompositions of the fit are most of the tracker's time.
    let lm = LevenbergMarquardt::new().with_ftol(1e-6).with_xtol(1e-6);
    // A sharp edge first, with the pixels away from the lines grouped; a blurred one (or an
    // edge that moved), where grouped pixels left their level, again per pixel from the start
    // (not from the grouped fit, whose optimum can lie in another valley).
    fit.group_flat(GROUP_BEYOND_PX);
    let (mut fit, report) = lm.minimize(fit);
    let mut ok = report.termination.was_successful();
    if !(ok && fit.groups_exact()) {
        fit.ungrouped();
        fit.set_params(&start);
        let (refit, report) = lm.minimize(fit);
        fit = refit;
        ok = report.termination.was_successful();
    }
    if !ok || !fit.p.iter().all(|v| v.is_finite()) {
        return None;
    }
    let line = |i: usize| {
        let normal = Vector2::new(fit.p[i].cos(), fit.p[i].sin());
        (
            mids[i] + normal * fit.p[4 + i],
            Vector2::new(-normal.y, normal.x),
        )
    };
    let mut out = *corners;
    for (i, corner) in out.iter_mut().enumerate() {
        let (p, u) = line((i + 3) % 4);
        let (q, v) = line(i);
        let cross = u.x * v.y - u.y * v.x;
        if cross.abs() < 1e-3 {
            return None;
        }
        let d = q - p;
        *corner = p + u * ((d.x * v.y - d.y * v.x) / cross);
    }
    out.iter()
        .zip(corners)
        .all(|(r, c)| (r - c).norm() <= MAX_SHIFT_PX)
        .then_some(out)
}
