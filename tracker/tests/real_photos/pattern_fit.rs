//! A fit of a whole tag to the pixels, as a judge of corner positions on real photographs that
//! shares neither the AprilTag quad fit nor odocal's edge model.
//!
//! The model is the tag as printed: its 10×10 cells (black ring, white border and the data bits
//! of its id) mapped into the image by the homography of the black square's four corners,
//! each pixel the mean over its area, then a Gaussian optical blur, dark and light levels and
//! a linear change of illumination across the tag. The corners, levels, blur and illumination
//! are found by Levenberg–Marquardt on every pixel of the tag out to the middle of its white
//! border. Because the data bits are part of the model, the light cells next to the black
//! ring cannot pull an edge (they do pull a quad fit on thresholded pixels, differently on
//! each side of the tag), and because it uses no gradient stencil or pixel sampling of its
//! own, it cannot share a detector's half-pixel mistake.
//!
//! Pixels are rendered with sub-samples, each averaging the cells over its own small box, so
//! the image is a continuous function of the corners and a finite-difference Jacobian works.

use nalgebra::{DMatrix, DVector, Matrix3, Point2, SMatrix, SVector, Vector3};
use odocal_tracker::GrayFrame;
use opencv::core::{Mat, Size, BORDER_REPLICATE};
use opencv::imgproc;
use opencv::prelude::*;

/// Sub-samples per pixel along each axis.
const SS: usize = 4;
/// Number of parameters: 4 corners (x, y), dark, light, ln(blur σ), illumination slopes in x, y.
const NP: usize = 13;
const DARK: usize = 8;
const LIGHT: usize = 9;
const LN_BLUR: usize = 10;
const SLOPE_X: usize = 11;
const SLOPE_Y: usize = 12;
/// Pixels whose centres lie within this many cells of the plate's outer edge are left out:
/// the middle of the white border and beyond, where the printed tag ends and whatever
/// surrounds it begins.
const OUTER_CELLS_LEFT_OUT: f64 = 0.5;

/// A tag's cells: `n`×`n` including the white border, row-major from the top, true = white.
pub struct TagCells {
    white: Vec<bool>,
    n: usize,
    at_border: usize,
}

impl TagCells {
    /// Cells of tag36h11 `id`, from the detector's own C library.
    pub fn tag36h11(id: u32) -> Self {
        let (white, n, at_border) =
            odocal_synth::scene::tag36h11_pattern(id).expect("a tag36h11 id");
        Self {
            white,
            n,
            at_border,
        }
    }

    /// Whether cell (col, row) is white under symmetry `d` of the square (bit 0 mirrors
    /// columns, bit 1 rows, bit 2 swaps them); outside the plate counts as white.
    fn white(&self, col: i64, row: i64, d: usize) -> bool {
        let n = self.n as i64;
        if !(0..n).contains(&col) || !(0..n).contains(&row) {
            return true;
        }
        let (mut c, mut r) = if d & 4 != 0 { (row, col) } else { (col, row) };
        if d & 1 != 0 {
            c = n - 1 - c;
        }
        if d & 2 != 0 {
            r = n - 1 - r;
        }
        self.white[(r * n + c) as usize]
    }
}

/// The fitted tag.
pub struct PatternFit {
    /// Corners of the black square, in the order they were given, pixels (OpenCV convention).
    pub corners: [Point2<f64>; 4],
    /// Optical blur, pixels (σ of the Gaussian).
    pub blur_px: f64,
    /// RMS of the residuals, grey levels.
    pub rms_grey: f64,
}

/// Homography from cell coordinates (0..n across the plate) to pixels, given the black
/// square's corners at cells (b, b), (n−b, b), (n−b, n−b), (b, n−b).
fn homography(corners: &[Point2<f64>; 4], n: f64, b: f64) -> Option<Matrix3<f64>> {
    let cells = [(b, b), (n - b, b), (n - b, n - b), (b, n - b)];
    let mut a = SMatrix::<f64, 8, 8>::zeros();
    let mut rhs = SVector::<f64, 8>::zeros();
    for (k, (&(x, y), p)) in cells.iter().zip(corners).enumerate() {
        let (u, v) = (p.x, p.y);
        let rows = [
            [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y],
            [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y],
        ];
        for (i, row) in rows.iter().enumerate() {
            for (j, &value) in row.iter().enumerate() {
                a[(2 * k + i, j)] = value;
            }
        }
        rhs[2 * k] = u;
        rhs[2 * k + 1] = v;
    }
    let h = a.lu().solve(&rhs)?;
    Some(Matrix3::new(
        h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0,
    ))
}

/// The pixels a fit uses: a rectangle of the frame and its grey levels.
struct Patch {
    x0: i64,
    y0: i64,
    w: usize,
    h: usize,
    grey: Vec<f64>,
}

impl Patch {
    /// The model's grey levels over the patch for parameters `p` and symmetry `d`, and which
    /// pixels count (inside the plate, short of its outer edge).
    fn render(&self, tag: &TagCells, d: usize, p: &[f64; NP]) -> Option<(Vec<f64>, Vec<bool>)> {
        let corners = [0, 1, 2, 3].map(|k| Point2::new(p[2 * k], p[2 * k + 1]));
        let (n, b) = (tag.n as f64, (tag.n - tag.at_border) as f64 / 2.0);
        let to_cells = homography(&corners, n, b)?.try_inverse()?;
        let cell_of = |x: f64, y: f64| {
            let q = to_cells * Vector3::new(x, y, 1.0);
            (q.x / q.z, q.y / q.z)
        };
        // Each sub-sample averages the cells over a box one sub-sample wide.
        let side_px = (0..4)
            .map(|k| (corners[(k + 1) % 4] - corners[k]).norm())
            .sum::<f64>()
            / 4.0;
        let eps = (tag.at_border as f64) / side_px / SS as f64;
        let overlap =
            |t: f64, i: f64| ((t + eps / 2.0).min(i + 1.0) - (t - eps / 2.0).max(i)).max(0.0) / eps;
        let (hw, hh) = (self.w * SS, self.h * SS);
        let mut fine = vec![0f32; hw * hh];
        for yy in 0..hh {
            for xx in 0..hw {
                let x = self.x0 as f64 - 0.5 + (xx as f64 + 0.5) / SS as f64;
                let y = self.y0 as f64 - 0.5 + (yy as f64 + 0.5) / SS as f64;
                let (u, v) = cell_of(x, y);
                let (iu, iv) = ((u - eps / 2.0).floor(), (v - eps / 2.0).floor());
                let mut light = 0.0;
                for di in 0..2 {
                    for dj in 0..2 {
                        let (i, j) = (iu + di as f64, iv + dj as f64);
                        if tag.white(i as i64, j as i64, d) {
                            light += overlap(u, i) * overlap(v, j);
                        }
                    }
                }
                fine[yy * hw + xx] = light as f32;
            }
        }
        let row = Mat::from_slice(&fine).ok()?;
        let fine = row.reshape(1, hh as i32).ok()?.try_clone().ok()?;
        let sigma = p[LN_BLUR].exp() * SS as f64;
        let mut blurred = Mat::default();
        imgproc::gaussian_blur(
            &fine,
            &mut blurred,
            Size::new(0, 0),
            sigma,
            sigma,
            BORDER_REPLICATE,
        )
        .ok()?;
        let blurred = blurred.data_typed::<f32>().ok()?;
        let (cx, cy) = (
            self.x0 as f64 + self.w as f64 / 2.0,
            self.y0 as f64 + self.h as f64 / 2.0,
        );
        let lo = OUTER_CELLS_LEFT_OUT;
        let hi = n - OUTER_CELLS_LEFT_OUT;
        let mut model = vec![0.0; self.w * self.h];
        let mut used = vec![false; self.w * self.h];
        for y in 0..self.h {
            for x in 0..self.w {
                let mut sum = 0.0;
                for sy in 0..SS {
                    let start = (y * SS + sy) * hw + x * SS;
                    sum += blurred[start..start + SS]
                        .iter()
                        .map(|&v| v as f64)
                        .sum::<f64>();
                }
                let t = sum / (SS * SS) as f64;
                let (px, py) = ((self.x0 + x as i64) as f64, (self.y0 + y as i64) as f64);
                let gain = 1.0 + p[SLOPE_X] * (px - cx) + p[SLOPE_Y] * (py - cy);
                model[y * self.w + x] = (p[DARK] + (p[LIGHT] - p[DARK]) * t) * gain;
                let (u, v) = cell_of(px, py);
                used[y * self.w + x] = (lo..=hi).contains(&u) && (lo..=hi).contains(&v);
            }
        }
        Some((model, used))
    }

    /// Residuals (model − pixel) of the pixels that count; 0 for the others.
    fn residuals(&self, tag: &TagCells, d: usize, p: &[f64; NP]) -> Option<Vec<f64>> {
        let (model, used) = self.render(tag, d, p)?;
        Some(
            model
                .iter()
                .zip(&self.grey)
                .zip(&used)
                .map(|((m, g), &u)| if u { m - g } else { 0.0 })
                .collect(),
        )
    }
}

fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Fits `tag` to `frame` starting from `start` (a detection's corners, within a pixel or so);
/// `None` near the image border or when the fit fails.
pub fn fit(frame: &GrayFrame, start: &[Point2<f64>; 4], tag: &TagCells) -> Option<PatternFit> {
    let side_px = (start[1] - start[0]).norm();
    // The plate reaches one cell beyond the black square; the blur a little further.
    let margin = side_px / tag.at_border as f64 * 1.5 + 3.0;
    let xs = start.iter().map(|p| p.x);
    let ys = start.iter().map(|p| p.y);
    let x0 = (xs.clone().fold(f64::INFINITY, f64::min) - margin).floor() as i64;
    let x1 = (xs.fold(f64::NEG_INFINITY, f64::max) + margin).ceil() as i64;
    let y0 = (ys.clone().fold(f64::INFINITY, f64::min) - margin).floor() as i64;
    let y1 = (ys.fold(f64::NEG_INFINITY, f64::max) + margin).ceil() as i64;
    if x0 < 0 || y0 < 0 || x1 >= frame.width as i64 || y1 >= frame.height as i64 {
        return None;
    }
    let (w, h) = ((x1 - x0 + 1) as usize, (y1 - y0 + 1) as usize);
    let mut grey = Vec::with_capacity(w * h);
    for y in y0..=y1 {
        let row = y as usize * frame.width as usize;
        grey.extend(
            frame.data[row + x0 as usize..=row + x1 as usize]
                .iter()
                .map(|&v| v as f64),
        );
    }
    let patch = Patch { x0, y0, w, h, grey };
    let mut p = [0.0; NP];
    for (k, c) in start.iter().enumerate() {
        p[2 * k] = c.x;
        p[2 * k + 1] = c.y;
    }
    p[DARK] = patch.grey.iter().copied().fold(f64::INFINITY, f64::min);
    p[LIGHT] = patch.grey.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    p[LN_BLUR] = 0.8f64.ln();
    // Which way round the pattern lies: the symmetry of the square that fits best at the start.
    let (d, _) = (0..8)
        .filter_map(|d| Some((d, sum_sq(&patch.residuals(tag, d, &p)?))))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let mut r = patch.residuals(tag, d, &p)?;
    let mut cost = sum_sq(&r);
    let mut lambda = 1e-3;
    let steps = [
        0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.1, 0.1, 0.01, 1e-4, 1e-4,
    ];
    for _ in 0..50 {
        let mut jac = DMatrix::<f64>::zeros(r.len(), NP);
        for (k, &step) in steps.iter().enumerate() {
            let mut q = p;
            q[k] += step;
            let rq = patch.residuals(tag, d, &q)?;
            for (i, (a, b)) in rq.iter().zip(&r).enumerate() {
                jac[(i, k)] = (a - b) / step;
            }
        }
        let jt = jac.transpose();
        let jtj = &jt * &jac;
        let g = &jt * DVector::from_column_slice(&r);
        let mut accepted = None;
        for _ in 0..12 {
            let mut a = jtj.clone();
            for k in 0..NP {
                a[(k, k)] *= 1.0 + lambda;
                a[(k, k)] += 1e-9;
            }
            let Some(dp) = a.lu().solve(&(-&g)) else {
                lambda *= 4.0;
                continue;
            };
            let mut q = p;
            for k in 0..NP {
                q[k] += dp[k];
            }
            let rq = patch.residuals(tag, d, &q)?;
            let cq = sum_sq(&rq);
            if cq < cost {
                lambda = (lambda / 3.0).max(1e-7);
                accepted = Some((q, rq, cq, dp.rows(0, 8).amax()));
                break;
            }
            lambda *= 4.0;
        }
        let Some((q, rq, cq, corner_step)) = accepted else {
            break;
        };
        (p, r, cost) = (q, rq, cq);
        if corner_step < 1e-4 {
            break;
        }
    }
    let used = r.iter().filter(|v| **v != 0.0).count().max(1);
    Some(PatternFit {
        corners: [0, 1, 2, 3].map(|k| Point2::new(p[2 * k], p[2 * k + 1])),
        blur_px: p[LN_BLUR].exp(),
        rms_grey: (cost / used as f64).sqrt(),
    })
}
