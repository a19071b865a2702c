//! The landmark map: reflectors with position, orientation and visibility
//! line, their sorted distance relations, walls and a spatial grid.

use std::path::Path;

use nalgebra::{Point2, Vector2};
use odocal_core::ray_segment;
use serde::{Deserialize, Serialize};

use crate::LrfError;

/// The `format` tag of a landmark map file.
pub const MAP_FORMAT: &str = "odocal.lrf-map/1";

/// Default acceptance half-angle of a flat retro-reflector around its normal.
const DEFAULT_HALF_FOV_RAD: f64 = 75.0 * std::f64::consts::PI / 180.0;

/// Which side of a visibility line a landmark can be seen from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// y > a·x + b.
    Above,
    /// y < a·x + b.
    Below,
    /// x < x_m (vertical line).
    Left,
    /// x > x_m (vertical line).
    Right,
}

/// A visibility boundary line: `y = a·x + b`, or the vertical line `x = x_m`,
/// and the side from which the landmark is visible.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VisibilityLine {
    /// Slope of `y = a·x + b` (absent for a vertical line).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a: Option<f64>,
    /// Intercept of `y = a·x + b` in metres (absent for a vertical line).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub b: Option<f64>,
    /// Abscissa of a vertical line `x = x_m`, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x_m: Option<f64>,
    /// The visible side.
    pub visible: Side,
}

/// One landmark as stored in the map file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LandmarkSpec {
    /// Unique identifier.
    pub id: u32,
    /// Position x, metres (map frame).
    pub x_m: f64,
    /// Position y, metres (map frame).
    pub y_m: f64,
    /// Direction the reflecting surface faces (its outward normal), radians; absent = visible from all directions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub facing_rad: Option<f64>,
    /// Acceptance half-angle around `facing_rad`, radians (default 75°).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub half_fov_rad: Option<f64>,
    /// Visibility boundary line (the landmark is only visible from one side).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub visibility_line: Option<VisibilityLine>,
}

/// The map file: `{"format": "odocal.lrf-map/1", "reflector_width_m": …, "landmarks": […], "walls": […]}`.
///
/// Keys odocal does not read are refused, not passed over: a misspelt or renamed one
/// (`facing_deg` for `facing_rad`) would leave its default in its place, and the poses
/// worse with no word.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapFile {
    /// Must be [`MAP_FORMAT`].
    pub format: String,
    /// Width of the reflective strips, metres (used to reject too-wide clusters).
    #[serde(default = "default_width")]
    pub reflector_width_m: f64,
    /// The landmarks.
    pub landmarks: Vec<LandmarkSpec>,
    /// Walls as segments `[x1, y1, x2, y2]` in metres (occluders; optional).
    #[serde(default)]
    pub walls: Vec<[f64; 4]>,
    /// Uncertainty (1 sigma) of each landmark's surveyed position, metres; absent = the
    /// localiser's default ([`crate::LocalizerConfig::map_sigma_m`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_sigma_m: Option<f64>,
    /// The room's width and height, metres, as `odocal synth lrf` writes them: for the
    /// reader's eye, not used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub room_m: Option<[f64; 2]>,
}

fn default_width() -> f64 {
    0.08
}

/// A landmark with its visibility model in ready-to-use form.
#[derive(Debug, Clone, PartialEq)]
pub struct Landmark {
    /// Identifier from the map file.
    pub id: u32,
    /// Position in the map frame, metres.
    pub position: Point2<f64>,
    /// Unit outward normal of the reflecting surface (None = omnidirectional).
    pub facing: Option<Vector2<f64>>,
    /// Acceptance half-angle around the normal, radians.
    pub half_fov_rad: f64,
    /// Visible half-plane `n·p ≥ c` with unit `n` (None = no line).
    pub half_plane: Option<(Vector2<f64>, f64)>,
}

impl Landmark {
    /// True if a sensor at `p` is in front of the reflector: inside its
    /// acceptance cone shrunk by `margin_rad` and on the visible side of its
    /// line by at least `margin_m`.
    pub fn visible_from(&self, p: &Point2<f64>, margin_rad: f64, margin_m: f64) -> bool {
        let v = p - self.position;
        let d = v.norm();
        if d < 1e-9 {
            return false;
        }
        if let Some(f) = self.facing {
            let lim = self.half_fov_rad - margin_rad;
            if lim <= 0.0 || f.dot(&v) < lim.cos() * d {
                return false;
            }
        }
        if let Some((n, c)) = self.half_plane {
            if n.dot(&p.coords) - c < margin_m {
                return false;
            }
        }
        true
    }
}

/// A uniform grid over the landmarks for radius queries.
#[derive(Debug, Clone)]
struct Grid {
    origin: Point2<f64>,
    cell_m: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Grid {
    fn new(pos: &[Point2<f64>], cell_m: f64) -> Grid {
        let (mut lo, mut hi) = (pos[0], pos[0]);
        for p in pos {
            lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
            hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
        }
        let origin = Point2::new(lo.x - cell_m, lo.y - cell_m);
        let nx = ((hi.x - origin.x) / cell_m).ceil() as usize + 2;
        let ny = ((hi.y - origin.y) / cell_m).ceil() as usize + 2;
        let mut cells = vec![Vec::new(); nx * ny];
        for (i, p) in pos.iter().enumerate() {
            let cx = ((p.x - origin.x) / cell_m) as usize;
            let cy = ((p.y - origin.y) / cell_m) as usize;
            cells[cy * nx + cx].push(i as u32);
        }
        let mut start = Vec::with_capacity(nx * ny + 1);
        let mut items = Vec::with_capacity(pos.len());
        for c in &cells {
            start.push(items.len() as u32);
            items.extend_from_slice(c);
        }
        start.push(items.len() as u32);
        Grid {
            origin,
            cell_m,
            nx,
            ny,
            start,
            items,
        }
    }

    /// Calls `f` for every item in the cells overlapping the square of half-size `r` around `p`.
    #[inline]
    fn for_each_near(&self, p: &Point2<f64>, r: f64, mut f: impl FnMut(usize)) {
        let fx0 = ((p.x - r - self.origin.x) / self.cell_m).floor();
        let fy0 = ((p.y - r - self.origin.y) / self.cell_m).floor();
        let fx1 = ((p.x + r - self.origin.x) / self.cell_m).floor();
        let fy1 = ((p.y + r - self.origin.y) / self.cell_m).floor();
        if fx1 < 0.0 || fy1 < 0.0 || fx0 >= self.nx as f64 || fy0 >= self.ny as f64 {
            return;
        }
        let x0 = fx0.max(0.0) as usize;
        let y0 = fy0.max(0.0) as usize;
        let x1 = (fx1 as usize).min(self.nx - 1);
        let y1 = (fy1 as usize).min(self.ny - 1);
        for cy in y0..=y1 {
            let row = cy * self.nx;
            let s = self.start[row + x0] as usize;
            let e = self.start[row + x1 + 1] as usize;
            for &i in &self.items[s..e] {
                f(i as usize);
            }
        }
    }
}

/// The landmark map with its search structures.
#[derive(Debug, Clone)]
pub struct Map {
    /// The landmarks, in file order.
    pub landmarks: Vec<Landmark>,
    /// Walls `[x1, y1, x2, y2]`, metres.
    pub walls: Vec<[f64; 4]>,
    /// Reflector strip width, metres.
    pub reflector_width_m: f64,
    /// Uncertainty (1 sigma) of each landmark's position as the file states it, metres.
    pub position_sigma_m: Option<f64>,
    /// Per landmark i, edges `edge_start[i]..edge_start[i+1]` sorted by distance.
    pub(crate) edge_start: Vec<usize>,
    /// Edge target landmark.
    pub(crate) edge_to: Vec<u32>,
    /// Edge length, metres (ascending within each landmark).
    pub(crate) edge_dist: Vec<f64>,
    /// Edge direction (from i to the target), radians in the map frame.
    pub(crate) edge_dir: Vec<f64>,
    /// All unordered pairs (a < b) sorted by distance.
    pub(crate) pair_dist: Vec<f64>,
    /// The pairs' landmarks.
    pub(crate) pair_ab: Vec<(u32, u32)>,
    grid: Grid,
}

/// The narrowest reflector strip a map may give, metres: a scanner's beams, a few millimetres
/// apart at a metre, could not tell a narrower one from a glint.
const MIN_REFLECTOR_WIDTH_M: f64 = 0.005;
/// The widest, metres: a strip a metre wide is a wall, and clusters that wide would pass for
/// reflectors.
const MAX_REFLECTOR_WIDTH_M: f64 = 1.0;

/// Grid cell size, metres (radius queries up to this size cost 3×3 cells).
const GRID_CELL_M: f64 = 0.5;

/// Whether one scanner can see both landmarks at once: their acceptance cones overlap (a
/// landmark without a facing is seen from every side). Strips on the two faces of a post
/// are not.
fn seen_together(a: &Landmark, b: &Landmark) -> bool {
    match (a.facing, b.facing) {
        (Some(fa), Some(fb)) => fa.angle(&fb) < a.half_fov_rad + b.half_fov_rad,
        _ => true,
    }
}

/// An unknown key's or a mistyped value's error with what to do about it: serde names an
/// unknown key, its line and column and the keys known there, but not that the units are in
/// the names; and a value of the wrong type (`"id": "3"`) by its type alone, not its key,
/// which is read back from `text` before the place named.
fn with_key_hint(e: odocal_core::FileError, text: &str) -> odocal_core::FileError {
    let odocal_core::FileError::Parse {
        path,
        line,
        column,
        message,
    } = e
    else {
        return e;
    };
    let message = if message.starts_with("unknown field") {
        format!(
            "{message}; spell the key as one of those known there, in the unit its name says (facing_rad in radians, x_m in metres), or remove it"
        )
    } else if message.starts_with("invalid type") {
        match key_before(text, line, column) {
            Some(key) => format!(
                "{message}: the value of `{key}`; give it as the type expected (a number without quotes)"
            ),
            None => message,
        }
    } else {
        message
    };
    odocal_core::FileError::Parse {
        path,
        line,
        column,
        message,
    }
}

/// The last `"key":` before `line`, `column` (1-based, as serde_json counts them) of `text`.
fn key_before(text: &str, line: u64, column: u64) -> Option<String> {
    let start: usize = text
        .split_inclusive('\n')
        .take(usize::try_from(line).ok()?.saturating_sub(1))
        .map(str::len)
        .sum();
    let rest = text.get(start..)?;
    let end = start
        + rest
            .char_indices()
            .nth(usize::try_from(column).ok()?)
            .map_or(rest.len(), |(i, _)| i);
    let before = text.get(..end)?;
    let colon = before.rfind(':')?;
    let key_end = before[..colon].trim_end().strip_suffix('"')?;
    let key_start = key_end.rfind('"')?;
    Some(key_end[key_start + 1..].to_string())
}

impl Map {
    /// Reads and validates a map file.
    pub fn read(path: &Path) -> Result<Map, LrfError> {
        let text = odocal_core::read_text(path)?;
        Map::parse(&text, &path.display().to_string())
    }

    /// Parses and validates map JSON; `name` is used in messages.
    pub fn parse(text: &str, name: &str) -> Result<Map, LrfError> {
        let file: MapFile = odocal_core::parse_tagged_json(
            text,
            name,
            MAP_FORMAT,
            "pass a landmark map (e.g. from `odocal synth lrf`)",
        )
        .map_err(|e| with_key_hint(e, text))?;
        Map::from_file(&file, name)
    }

    /// Builds the map and its sorted relations from a parsed file; `name` is used in messages.
    pub fn from_file(file: &MapFile, name: &str) -> Result<Map, LrfError> {
        let err = |message: String| LrfError::Map {
            path: name.to_string(),
            message,
        };
        if file.format != MAP_FORMAT {
            return Err(err(format!(
                "format is \"{}\", expected \"{MAP_FORMAT}\"",
                file.format
            )));
        }
        let n = file.landmarks.len();
        if n < 3 {
            return Err(err(format!(
                "has {n} landmark(s); at least 3 are needed to fix a pose — add landmarks"
            )));
        }
        if !(file.reflector_width_m.is_finite() && file.reflector_width_m > 0.0) {
            return Err(err(format!(
                "reflector_width_m is {}; give the strip width in metres (> 0)",
                file.reflector_width_m
            )));
        }
        let w = file.reflector_width_m;
        if !(MIN_REFLECTOR_WIDTH_M..MAX_REFLECTOR_WIDTH_M).contains(&w) {
            return Err(err(format!(
                "reflector_width_m is {w} m, but a reflector strip is {:.0} mm to well under {MAX_REFLECTOR_WIDTH_M:.0} m wide: is it in millimetres (if so, {w} mm is {:.3} m)? Give the strip width in metres",
                MIN_REFLECTOR_WIDTH_M * 1e3,
                w / 1000.0
            )));
        }
        if let Some(s) = file.position_sigma_m {
            if !(s.is_finite() && (0.0..1.0).contains(&s)) {
                return Err(err(format!(
                    "position_sigma_m is {s}; give the landmarks' survey uncertainty in metres (0 to 1)"
                )));
            }
        }
        let mut landmarks = Vec::with_capacity(n);
        for (k, s) in file.landmarks.iter().enumerate() {
            let at = format!("landmark #{k} (id {})", s.id);
            let finite = [Some(s.x_m), Some(s.y_m), s.facing_rad, s.half_fov_rad]
                .iter()
                .flatten()
                .all(|v| v.is_finite());
            if !finite {
                return Err(err(format!(
                    "{at}: a number is not finite; fix the coordinates"
                )));
            }
            if let Some(a) = s
                .facing_rad
                .filter(|a| a.abs() > std::f64::consts::TAU + 1e-9)
            {
                return Err(err(format!(
                    "{at}: facing_rad {a} is beyond a full turn; angles are in radians (if it is in degrees, {a}° is {:.4} rad)",
                    a.to_radians()
                )));
            }
            let half_fov_rad = s.half_fov_rad.unwrap_or(DEFAULT_HALF_FOV_RAD);
            if !(half_fov_rad > 0.0 && half_fov_rad <= std::f64::consts::PI) {
                return Err(err(format!(
                    "{at}: half_fov_rad {half_fov_rad} is outside (0, pi]; angles are in radians (if it is in degrees, {half_fov_rad}° is {:.4} rad)",
                    half_fov_rad.to_radians()
                )));
            }
            let half_plane = match s.visibility_line {
                None => None,
                Some(l) => {
                    Some(half_plane(&l).map_err(|m| err(format!("{at}: visibility_line {m}")))?)
                }
            };
            landmarks.push(Landmark {
                id: s.id,
                position: Point2::new(s.x_m, s.y_m),
                facing: s.facing_rad.map(|a| Vector2::new(a.cos(), a.sin())),
                half_fov_rad,
                half_plane,
            });
        }
        let mut ids: Vec<(u32, usize)> = landmarks
            .iter()
            .enumerate()
            .map(|(k, l)| (l.id, k))
            .collect();
        ids.sort_unstable();
        for w in ids.windows(2) {
            if w[0].0 == w[1].0 {
                return Err(err(format!(
                    "landmarks #{} and #{} share id {}; give every landmark its own id",
                    w[0].1, w[1].1, w[0].0
                )));
            }
        }
        for (k, w) in file.walls.iter().enumerate() {
            if !w.iter().all(|v| v.is_finite()) {
                return Err(err(format!("wall #{k}: a coordinate is not finite")));
            }
        }
        let pos: Vec<Point2<f64>> = landmarks.iter().map(|l| l.position).collect();
        check_extent(&pos, n).map_err(err)?;
        Map::build(
            landmarks,
            file.walls.clone(),
            file.reflector_width_m,
            file.position_sigma_m,
        )
        .map_err(err)
    }

    /// The same map without the landmarks `ids` (moved since it was made, say), None when
    /// fewer than 3 would be left to fix a pose.
    pub fn without(&self, ids: &[u32]) -> Option<Map> {
        let landmarks: Vec<Landmark> = self
            .landmarks
            .iter()
            .filter(|l| !ids.contains(&l.id))
            .cloned()
            .collect();
        if landmarks.len() < 3 {
            return None;
        }
        self.with_landmarks(landmarks)
    }

    /// This map's walls, reflector width and survey σ around other `landmarks` (a subset of
    /// its own, or its own changed), None if they do not make a map.
    fn with_landmarks(&self, landmarks: Vec<Landmark>) -> Option<Map> {
        Map::build(
            landmarks,
            self.walls.clone(),
            self.reflector_width_m,
            self.position_sigma_m,
        )
        .ok()
    }

    /// The map's sorted relations and grid for checked `landmarks`; an error names two
    /// landmarks at one place, or touching where one beam sees both.
    fn build(
        landmarks: Vec<Landmark>,
        walls: Vec<[f64; 4]>,
        reflector_width_m: f64,
        position_sigma_m: Option<f64>,
    ) -> Result<Map, String> {
        let n = landmarks.len();
        let pos: Vec<Point2<f64>> = landmarks.iter().map(|l| l.position).collect();
        // Edges per landmark, sorted by distance (the source's map structure).
        let mut edge_start = Vec::with_capacity(n + 1);
        let (mut edge_to, mut edge_dist, mut edge_dir) = (Vec::new(), Vec::new(), Vec::new());
        let mut pairs: Vec<(f64, u32, u32)> = Vec::with_capacity(n * (n - 1) / 2);
        for i in 0..n {
            edge_start.push(edge_to.len());
            let mut e: Vec<(f64, u32, f64)> = (0..n)
                .filter(|&j| j != i)
                .map(|j| {
                    let d = pos[j] - pos[i];
                    (d.norm(), j as u32, d.y.atan2(d.x))
                })
                .collect();
            e.sort_by(|a, b| a.0.total_cmp(&b.0));
            if let Some(first) = e.first() {
                if first.0 < 0.01 {
                    return Err(format!(
                        "landmarks id {} and id {} are {:.4} m apart (duplicates?); remove one or fix its position",
                        landmarks[i].id, landmarks[first.1 as usize].id, first.0
                    ));
                }
            }
            // Strips closer than a strip's width, seen from one side, touch: the scanner reads
            // them as one detection between the two (3 cm apart, one was never named).
            let touching = e
                .iter()
                .take_while(|(d, ..)| *d < reflector_width_m)
                .find(|(_, j, _)| seen_together(&landmarks[i], &landmarks[*j as usize]));
            if let Some(&(d, j, _)) = touching {
                return Err(format!(
                    "landmarks id {} and id {} are {d:.3} m apart, less than a reflector's width ({reflector_width_m} m), and a beam can see both: strips that close read as one; remove one, fix its position, or give each its facing_rad if they face apart",
                    landmarks[i].id, landmarks[j as usize].id
                ));
            }
            for (d, j, a) in e {
                edge_to.push(j);
                edge_dist.push(d);
                edge_dir.push(a);
                if (i as u32) < j {
                    pairs.push((d, i as u32, j));
                }
            }
        }
        edge_start.push(edge_to.len());
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Cells grow with the map so that a large map's grid stays within a million cells.
        let span = |f: fn(&Point2<f64>) -> f64| {
            let v = pos.iter().map(f);
            v.clone().fold(f64::MIN, f64::max) - v.fold(f64::MAX, f64::min)
        };
        let span_m = span(|p| p.x).max(span(|p| p.y));
        let grid = Grid::new(&pos, GRID_CELL_M.max(span_m / 500.0));
        Ok(Map {
            landmarks,
            walls,
            reflector_width_m,
            position_sigma_m,
            edge_start,
            edge_to,
            edge_dist,
            edge_dir,
            pair_dist: pairs.iter().map(|p| p.0).collect(),
            pair_ab: pairs.iter().map(|p| (p.1, p.2)).collect(),
            grid,
        })
    }

    /// Landmarks that no scan by a scanner of range `max_range_m` sees with another one: their
    /// nearest other landmark is farther than twice the range. Such a landmark cannot help fix
    /// a pose, which needs several; far from all others it is most likely a mistyped
    /// coordinate. Each as (id, position, distance to its nearest other landmark in metres).
    pub fn isolated(&self, max_range_m: f64) -> Vec<(u32, Point2<f64>, f64)> {
        (0..self.len())
            .filter_map(|i| {
                let nearest = *self.edge_dist.get(self.edge_start[i])?;
                let l = &self.landmarks[i];
                (nearest > 2.0 * max_range_m).then_some((l.id, l.position, nearest))
            })
            .collect()
    }

    /// The map with every landmark's facing left out (seen from every side), or None if it
    /// has no facing to leave out.
    pub fn without_facings(&self) -> Option<Map> {
        if self.landmarks.iter().all(|l| l.facing.is_none()) {
            return None;
        }
        let landmarks: Vec<Landmark> = self
            .landmarks
            .iter()
            .map(|l| Landmark {
                facing: None,
                ..l.clone()
            })
            .collect();
        self.with_landmarks(landmarks)
    }

    /// True if `p` lies in the convex hull of the landmarks grown by `margin_m` (within
    /// `margin_m` of it). A scanner fixed by reflectors around it stands among them; a
    /// recording whose poses lie mostly outside them was fitted to a map that is not the room's.
    pub fn within_hull(&self, p: &Point2<f64>, margin_m: f64) -> bool {
        let hull = self.hull();
        match hull.len() {
            0 => false,
            1 => (p - hull[0]).norm() <= margin_m,
            _ => {
                let n = hull.len();
                let inside = n > 2
                    && (0..n).all(|i| {
                        let (a, b) = (hull[i], hull[(i + 1) % n]);
                        (b - a).perp(&(p - a)) >= 0.0
                    });
                inside
                    || (0..n).any(|i| {
                        let (a, b) = (hull[i], hull[(i + 1) % n]);
                        let ab = b - a;
                        let w = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                        (p - (a + ab * w)).norm() <= margin_m
                    })
            }
        }
    }

    /// The landmarks' convex hull, counter-clockwise (Andrew's monotone chain).
    fn hull(&self) -> Vec<Point2<f64>> {
        let mut pts: Vec<Point2<f64>> = self.landmarks.iter().map(|l| l.position).collect();
        pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        pts.dedup();
        if pts.len() < 3 {
            return pts;
        }
        let turn = |o: Point2<f64>, a: Point2<f64>, b: Point2<f64>| (a - o).perp(&(b - o));
        let mut h: Vec<Point2<f64>> = Vec::with_capacity(2 * pts.len());
        for pass in 0..2 {
            let start = h.len();
            let order: Vec<Point2<f64>> = if pass == 0 {
                pts.clone()
            } else {
                pts.iter().rev().copied().collect()
            };
            for p in order {
                while h.len() >= start + 2 && turn(h[h.len() - 2], h[h.len() - 1], p) <= 0.0 {
                    h.pop();
                }
                h.push(p);
            }
            h.pop();
        }
        h
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.landmarks.len()
    }

    /// True if the map has no landmarks (never, for a validated map).
    pub fn is_empty(&self) -> bool {
        self.landmarks.is_empty()
    }

    /// Position of landmark `i`.
    #[inline]
    pub fn position(&self, i: usize) -> Point2<f64> {
        self.landmarks[i].position
    }

    /// The nearest landmark to `p` within `gate_m` (≤ 0.5 m) satisfying `allow`, with its distance.
    #[inline]
    pub fn nearest_within(
        &self,
        p: &Point2<f64>,
        gate_m: f64,
        allow: impl Fn(usize) -> bool,
    ) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        let g2 = gate_m * gate_m;
        self.grid.for_each_near(p, gate_m, |i| {
            let d2 = (self.landmarks[i].position - p).norm_squared();
            if d2 <= g2 && best.is_none_or(|b| d2 < b.1) && allow(i) {
                best = Some((i, d2));
            }
        });
        best.map(|(i, d2)| (i, d2.sqrt()))
    }

    /// Calls `f` for every landmark within `r_m` of `p`.
    pub fn for_each_within(&self, p: &Point2<f64>, r_m: f64, mut f: impl FnMut(usize)) {
        let r2 = r_m * r_m;
        self.grid.for_each_near(p, r_m, |i| {
            if (self.landmarks[i].position - p).norm_squared() <= r2 {
                f(i)
            }
        });
    }

    /// Edges of landmark `i` whose length is within `[lo, hi]`: indices into the edge arrays (binary search).
    #[inline]
    pub(crate) fn edges_in(&self, i: usize, lo: f64, hi: f64) -> std::ops::Range<usize> {
        let (s, e) = (self.edge_start[i], self.edge_start[i + 1]);
        let d = &self.edge_dist[s..e];
        let a = d.partition_point(|&x| x < lo);
        let b = d.partition_point(|&x| x <= hi);
        s + a..s + b
    }

    /// Distance from `from` along the unit direction `dir` to the nearest wall, if any.
    pub fn ray_to_wall(&self, from: &Point2<f64>, dir: &Vector2<f64>) -> Option<f64> {
        let mut best: Option<f64> = None;
        for w in &self.walls {
            let (a, b) = (Point2::new(w[0], w[1]), Point2::new(w[2], w[3]));
            let Some((t, u)) = ray_segment(from, dir, &a, &b) else {
                continue;
            };
            if t > 1e-6 && (0.0..=1.0).contains(&u) && best.is_none_or(|b| t < b) {
                best = Some(t);
            }
        }
        best
    }

    /// True if the straight path from `from` to `to` crosses a wall, ignoring
    /// the last `end_clear_m` before `to` (a reflector mounted on that wall).
    pub fn occluded(&self, from: &Point2<f64>, to: &Point2<f64>, end_clear_m: f64) -> bool {
        let d = to - from;
        let len = d.norm();
        if len < 1e-9 {
            return false;
        }
        let t_max = 1.0 - end_clear_m / len;
        self.walls.iter().any(|w| {
            let (a, b) = (Point2::new(w[0], w[1]), Point2::new(w[2], w[3]));
            ray_segment(from, &d, &a, &b)
                .is_some_and(|(t, u)| t > 1e-6 && t < t_max && (-1e-9..=1.0 + 1e-9).contains(&u))
        })
    }
}

/// The most landmarks a map may hold: the map keeps every pair (n² / 2 edges).
pub const MAX_LANDMARKS: usize = 2000;
/// The largest span of a map, metres: a building's reflector layout, not a city's.
pub const MAX_EXTENT_M: f64 = 2000.0;

/// Refuses maps whose size no building has (and whose search structures would not fit in
/// memory): too many landmarks, or landmarks spread over more than [`MAX_EXTENT_M`], as
/// coordinates in millimetres would be.
fn check_extent(pos: &[Point2<f64>], n: usize) -> Result<(), String> {
    if n > MAX_LANDMARKS {
        return Err(format!(
            "has {n} landmarks, more than the {MAX_LANDMARKS} a map may hold; split the map"
        ));
    }
    let (mut lo, mut hi) = (pos[0], pos[0]);
    for p in pos {
        lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    let (w, h) = (hi.x - lo.x, hi.y - lo.y);
    if !(w <= MAX_EXTENT_M && h <= MAX_EXTENT_M) {
        return Err(format!(
            "landmarks span {w:.3e} m x {h:.3e} m, more than the {MAX_EXTENT_M:.0} m a map covers; are the coordinates in metres?"
        ));
    }
    Ok(())
}

fn half_plane(l: &VisibilityLine) -> Result<(Vector2<f64>, f64), String> {
    match (l.a, l.b, l.x_m, l.visible) {
        (Some(a), Some(b), None, s @ (Side::Above | Side::Below)) if a.is_finite() && b.is_finite() => {
            let k = (1.0 + a * a).sqrt();
            let (n, c) = (Vector2::new(-a, 1.0) / k, b / k);
            Ok(if s == Side::Above { (n, c) } else { (-n, -c) })
        }
        (None, None, Some(x), s @ (Side::Left | Side::Right)) if x.is_finite() => Ok(if s == Side::Right {
            (Vector2::new(1.0, 0.0), x)
        } else {
            (Vector2::new(-1.0, 0.0), -x)
        }),
        _ => Err("must be {\"a\", \"b\", \"visible\": \"above\"|\"below\"} or {\"x_m\", \"visible\": \"left\"|\"right\"} with finite numbers".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(id: u32, x: f64, y: f64) -> LandmarkSpec {
        LandmarkSpec {
            id,
            x_m: x,
            y_m: y,
            facing_rad: None,
            half_fov_rad: None,
            visibility_line: None,
        }
    }

    fn file(l: Vec<LandmarkSpec>) -> MapFile {
        MapFile {
            format: MAP_FORMAT.into(),
            reflector_width_m: 0.08,
            landmarks: l,
            walls: vec![],
            position_sigma_m: None,
            room_m: None,
        }
    }

    #[test]
    fn edges_are_sorted_and_searchable() {
        let m = Map::from_file(
            &file(vec![
                spec(1, 0.0, 0.0),
                spec(2, 3.0, 0.0),
                spec(3, 0.0, 1.0),
                spec(4, 2.0, 2.0),
            ]),
            "t",
        )
        .unwrap();
        for i in 0..m.len() {
            let r = m.edge_start[i]..m.edge_start[i + 1];
            assert_eq!(r.len(), 3);
            assert!(m.edge_dist[r.clone()].windows(2).all(|w| w[0] <= w[1]));
        }
        let r = m.edges_in(0, 2.9, 3.1);
        assert_eq!(r.len(), 1);
        assert_eq!(m.edge_to[r.start], 1);
        assert!(m.pair_dist.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(
            m.nearest_within(&Point2::new(2.1, 1.9), 0.3, |_| true)
                .map(|x| x.0),
            Some(3)
        );
        assert_eq!(
            m.nearest_within(&Point2::new(2.5, 1.0), 0.3, |_| true),
            None
        );
    }

    #[test]
    fn rejects_bad_maps() {
        let e = Map::from_file(&file(vec![spec(1, 0.0, 0.0), spec(2, 1.0, 0.0)]), "m.json")
            .unwrap_err();
        assert!(e.to_string().contains("at least 3"), "{e}");
        let e = Map::from_file(
            &file(vec![
                spec(1, 0.0, 0.0),
                spec(1, 1.0, 0.0),
                spec(3, 0.0, 1.0),
            ]),
            "m",
        )
        .unwrap_err();
        assert!(e.to_string().contains("share id 1"), "{e}");
        let e = Map::from_file(
            &file(vec![
                spec(1, 0.0, 0.0),
                spec(2, 0.001, 0.0),
                spec(3, 0.0, 1.0),
            ]),
            "m",
        )
        .unwrap_err();
        assert!(e.to_string().contains("apart"), "{e}");
        // Strips 3 cm apart, closer than their 8 cm width: one detection for two, refused;
        // the same two on the opposite faces of a post are never seen together.
        let e = Map::from_file(
            &file(vec![
                spec(1, 0.0, 0.0),
                spec(2, 0.03, 0.0),
                spec(3, 0.0, 1.0),
            ]),
            "m",
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("landmarks id 1 and id 2 are 0.030 m apart, less than a reflector's width (0.08 m), and a beam can see both"),
            "{e}"
        );
        let mut post = file(vec![
            spec(1, 0.0, 0.0),
            spec(2, 0.03, 0.0),
            spec(3, 0.0, 1.0),
        ]);
        post.landmarks[0].facing_rad = Some(std::f64::consts::PI);
        post.landmarks[1].facing_rad = Some(0.0);
        assert!(Map::from_file(&post, "m").is_ok());
        // A width in millimetres: 80 "m".
        let mut f = file(vec![
            spec(1, 0.0, 0.0),
            spec(2, 1.0, 0.0),
            spec(3, 0.0, 1.0),
        ]);
        f.reflector_width_m = 80.0;
        let e = Map::from_file(&f, "m.json").unwrap_err();
        assert!(
            e.to_string().contains(
                "reflector_width_m is 80 m, but a reflector strip is 5 mm to well under 1 m wide: is it in millimetres (if so, 80 mm is 0.080 m)?"
            ),
            "{e}"
        );
        let e = Map::parse(r#"{"format": "odocal.camera/1"}"#, "m").unwrap_err();
        assert!(
            e.to_string().contains("expected \"odocal.lrf-map/1\""),
            "{e}"
        );
    }

    /// A landmark 50 m from the others of a 10 m x 8 m room (a mistyped 5.0): no scan sees it
    /// with another, and it is named; the room's own landmarks are not.
    #[test]
    fn a_landmark_far_from_all_others_is_isolated() {
        let room = [(1.0, 1.0), (9.0, 1.0), (9.0, 7.0), (1.0, 7.0), (5.0, 4.0)];
        let mut l: Vec<LandmarkSpec> = room
            .iter()
            .enumerate()
            .map(|(k, &(x, y))| spec(k as u32 + 1, x, y))
            .collect();
        let m = Map::from_file(&file(l.clone()), "m").unwrap();
        assert!(m.isolated(5.6).is_empty());
        l.push(spec(31, 55.0, 1.0));
        let m = Map::from_file(&file(l), "m").unwrap();
        let iso = m.isolated(5.6);
        assert_eq!(iso.len(), 1, "{iso:?}");
        assert_eq!(iso[0].0, 31);
        assert!((iso[0].2 - 46.0).abs() < 1e-9, "{iso:?}");
    }

    #[test]
    fn visibility_uses_facing_and_line() {
        let mut s = spec(1, 0.0, 0.0);
        s.facing_rad = Some(std::f64::consts::FRAC_PI_2);
        s.visibility_line = Some(VisibilityLine {
            a: Some(0.0),
            b: Some(0.0),
            x_m: None,
            visible: Side::Above,
        });
        let m = Map::from_file(&file(vec![s, spec(2, 5.0, 5.0), spec(3, -5.0, 5.0)]), "m").unwrap();
        let l = &m.landmarks[0];
        assert!(l.visible_from(&Point2::new(0.5, 2.0), 0.0, 0.0));
        assert!(!l.visible_from(&Point2::new(0.5, -2.0), 0.0, 0.0));
        assert!(
            !l.visible_from(&Point2::new(5.0, 0.5), 0.0, 0.0),
            "outside the 75° cone"
        );
    }
}
