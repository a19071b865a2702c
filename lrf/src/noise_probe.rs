//! Whether a wider range noise than the one given finds the poses a run left lost or
//! ambiguous: the association gates and the pose search's margins are a few σ of
//! `sigma_range_m` wide, so a σ below the scanner's own noise turns the true pose away and
//! reads, from the outside, like a wrong map. Likewise whether the scans mirrored find them:
//! a scanner mounted upside down takes its angles clockwise, and its scans fit the map nowhere
//! (or, by coincidence, somewhere far off).

use crate::localize::localize_scans;
use crate::pose_log::PoseLog;
use crate::scan::Scan;
use crate::search::{Localizer, Status};

/// Scans tried at each wider noise: enough to tell most from few, few enough to cost
/// milliseconds.
const PROBE_SCANS: usize = 20;
/// Factors tried on the given σ, smallest first: σ given in the wrong unit or by a place
/// value can be a thousand times too small.
/// Then smaller ones: a σ far above the scanner's noise widens the gates until every scan
/// fits the map in several places (`--sigma-range-m 0.2` left all 100 scans ambiguous, and
/// the map was blamed).
const FACTORS: [f64; 10] = [
    3.0,
    10.0,
    30.0,
    100.0,
    300.0,
    1000.0,
    1.0 / 3.0,
    0.1,
    1.0 / 30.0,
    0.01,
];
/// No scanner of this kind is less noisy than this (1σ), metres.
const MIN_SIGMA_RANGE_M: f64 = 0.0005;
/// No scanner of this kind is noisier than this (1σ), metres: wider gates stop telling
/// landmarks apart, and a "pose" found with them says nothing of the σ.
const MAX_SIGMA_RANGE_M: f64 = 0.05;
/// Share of the probed scans that must find a pose for the wider σ to be named.
const MIN_SHARE_OK: f64 = 0.8;

/// A wider range noise under which most probed scans find a pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WiderNoise {
    /// The range noise tried, metres (1σ).
    pub sigma_range_m: f64,
    /// Scans probed (the first of the run).
    pub n_scans: usize,
    /// Of them, found a pose with `loc`'s own σ.
    pub n_ok_given: usize,
    /// Of them, found a pose with `sigma_range_m`.
    pub n_ok_wider: usize,
}

/// Localises the first scans again with 3, 10, 30, … 1000 times `loc`'s range noise (up to
/// 5 cm), then with a third, a tenth, … a hundredth of it (down to 0.5 mm), and
/// returns the first under which at least 80 % of them, and more than with `loc`'s own σ,
/// find a pose. None when no wider σ does: the cause is then elsewhere.
pub fn wider_noise_finds_poses(
    loc: &Localizer,
    scans: &[Scan],
    rate_hz: f64,
    global_only: bool,
) -> Option<WiderNoise> {
    let scans = &scans[..scans.len().min(PROBE_SCANS)];
    if scans.is_empty() {
        return None;
    }
    let n_ok = |l: &Localizer| {
        let run = localize_scans(l, scans, rate_hz, global_only, &|| {});
        run.log
            .rows
            .iter()
            .filter(|r| r.status == Status::Ok && r.pose.is_some())
            .count()
    };
    let n_ok_given = n_ok(loc);
    let given = loc.cfg.sensor.sigma_range_m;
    FACTORS
        .iter()
        // Rounded, as the option would be written.
        .map(|f| (f * given * 1e6).round() / 1e6)
        .filter(|&s| (MIN_SIGMA_RANGE_M..=MAX_SIGMA_RANGE_M).contains(&s))
        .find_map(|sigma_range_m| {
            let mut cfg = loc.cfg;
            cfg.sensor.sigma_range_m = sigma_range_m;
            let n_ok_wider = n_ok(&Localizer::new(loc.map.clone(), cfg));
            (n_ok_wider > n_ok_given && n_ok_wider as f64 >= MIN_SHARE_OK * scans.len() as f64)
                .then_some(WiderNoise {
                    sigma_range_m,
                    n_scans: scans.len(),
                    n_ok_given,
                    n_ok_wider,
                })
        })
}

/// Scans found a pose with their angles mirrored ([`Scan::mirrored`]) where as given they
/// found few.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mirrored {
    /// Scans probed (the first of the run).
    pub n_scans: usize,
    /// Of them, found a pose as given.
    pub n_ok_given: usize,
    /// Of them, found a pose mirrored.
    pub n_ok_mirrored: usize,
}

/// Localises the first scans again mirrored (angles negated, as a scanner mounted upside
/// down takes them) and returns the counts when at least 80 % of them, and more than twice as
/// many as given, find a pose: the scanner's angles run the other way round than the map's.
/// None otherwise.
pub fn mirrored_finds_poses(
    loc: &Localizer,
    scans: &[Scan],
    rate_hz: f64,
    global_only: bool,
) -> Option<Mirrored> {
    let scans = &scans[..scans.len().min(PROBE_SCANS)];
    if scans.is_empty() {
        return None;
    }
    let n_ok = |s: &[Scan]| {
        let run = localize_scans(loc, s, rate_hz, global_only, &|| {});
        run.log
            .rows
            .iter()
            .filter(|r| r.status == Status::Ok && r.pose.is_some())
            .count()
    };
    let n_ok_given = n_ok(scans);
    let mirrored: Vec<Scan> = scans.iter().map(Scan::mirrored).collect();
    let n_ok_mirrored = n_ok(&mirrored);
    (n_ok_mirrored > 2 * n_ok_given && n_ok_mirrored as f64 >= MIN_SHARE_OK * scans.len() as f64)
        .then_some(Mirrored {
            n_scans: scans.len(),
            n_ok_given,
            n_ok_mirrored,
        })
}

/// Scans probed mirrored against a recording whose poses lie outside the landmarks: enough
/// for a share that tells, few enough to cost a tenth of a second.
const MIRROR_PROBE_SCANS: usize = 100;
/// A pose within this of the landmarks' hull is among them, metres: a reflector on a wall
/// and the robot a step from it.
pub const HULL_MARGIN_M: f64 = 0.5;

/// A recording whose `ok` poses lie mostly outside the landmarks, while its scans mirrored fit
/// the map among them ([`mirror_fits_better`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MirrorFits {
    /// `ok` poses of the recording as given ...
    pub n_ok_given: usize,
    /// ... and of them, outside the landmarks' hull.
    pub n_outside_given: usize,
    /// Scans probed mirrored (the first of the run) ...
    pub n_scans: usize,
    /// ... of them, found a pose ...
    pub n_ok_mirrored: usize,
    /// ... outside the landmarks' hull.
    pub n_outside_mirrored: usize,
    /// Of the same first scans as given, found a pose ...
    pub n_ok_first: usize,
    /// ... outside the landmarks' hull.
    pub n_outside_first: usize,
}

/// The poses of `log` that are `ok`, and of them those outside `loc`'s landmarks' hull (by
/// [`HULL_MARGIN_M`]).
pub fn poses_outside(loc: &Localizer, log: &PoseLog) -> (usize, usize) {
    let ok: Vec<_> = log
        .rows
        .iter()
        .filter(|r| r.status == Status::Ok)
        .filter_map(|r| r.pose)
        .collect();
    let outside = ok
        .iter()
        .filter(|p| {
            !loc.map
                .within_hull(&nalgebra::Point2::new(p.x_m, p.y_m), HULL_MARGIN_M)
        })
        .count();
    (ok.len(), outside)
}

/// The scans' angles run the other way round than the map's, though most scans found a pose:
/// a map of landmarks alone mirrored to the room (y flipped, or x and y swapped) fits its
/// scans by coincidence of a few landmarks, 232 of 300 scans `ok` and 12 m off, almost all
/// outside the landmarks. Returns the counts when most of `given`'s `ok` poses lie outside
/// the landmarks' hull, and the first scans mirrored ([`Scan::mirrored`]) find a pose, 80 %
/// of them or more, most among the landmarks and more than twice as many there as given.
/// None otherwise: a robot driving along a row of reflectors is outside their hull either
/// way, and a map symmetric by reflection fits the scans mirrored as well as not.
pub fn mirror_fits_better(
    loc: &Localizer,
    scans: &[Scan],
    rate_hz: f64,
    global_only: bool,
    given: &PoseLog,
) -> Option<MirrorFits> {
    let (n_ok_given, n_outside_given) = poses_outside(loc, given);
    if n_ok_given == 0 || n_outside_given * 2 <= n_ok_given {
        return None;
    }
    let scans = &scans[..scans.len().min(MIRROR_PROBE_SCANS)];
    let mirrored: Vec<Scan> = scans.iter().map(Scan::mirrored).collect();
    let run = localize_scans(loc, &mirrored, rate_hz, global_only, &|| {});
    let (n_ok_mirrored, n_outside_mirrored) = poses_outside(loc, &run.log);
    let first = PoseLog {
        rows: given.rows.iter().take(scans.len()).cloned().collect(),
    };
    let (n_ok_first, n_outside_first) = poses_outside(loc, &first);
    let among = |ok: usize, outside: usize| ok - outside;
    (n_ok_mirrored as f64 >= MIN_SHARE_OK * scans.len() as f64
        && n_outside_mirrored * 4 <= n_ok_mirrored
        && among(n_ok_mirrored, n_outside_mirrored) > 2 * among(n_ok_first, n_outside_first))
    .then_some(MirrorFits {
        n_ok_given,
        n_outside_given,
        n_scans: scans.len(),
        n_ok_mirrored,
        n_outside_mirrored,
        n_ok_first,
        n_outside_first,
    })
}

/// A reflector in a room faces the scanner within its acceptance angle wherever it is seen
/// from: the landmarks' facings, averaged around the circle, lie this far off the direction
/// to the scanner only when they follow another convention, radians (45°).
pub const MAX_FACING_OFFSET_RAD: f64 = std::f64::consts::FRAC_PI_4;

/// Scans found a pose with the map's facings left out, and the scanner sees the landmarks
/// from far off the way their facings say they face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FacingsOff {
    /// Scans probed (the first of the run) ...
    pub n_scans: usize,
    /// ... of them, found a pose as given ...
    pub n_ok_given: usize,
    /// ... and with the facings left out.
    pub n_ok_free: usize,
    /// The mean angle (around the circle) from a landmark's mapped facing to the scanner at
    /// those poses (for the landmarks in range and not behind a wall), radians: near 0 for
    /// facings right, near ±π/2 for facings measured from another axis, near π for facings
    /// into the wall.
    pub offset_rad: f64,
}

/// Localises the first scans again with the map's facings left out ([`Map::without_facings`])
/// and returns the counts when 80 % of them find a pose, no fewer than with the facings, and
/// at those poses the landmarks in range lie, on average, more than
/// [`MAX_FACING_OFFSET_RAD`] off the way their facings say they face: a facing_rad of
/// another convention (90° off: 162 of 200 `ok`, 10 beyond 5σ and up to 3.4 m off; reversed:
/// 7 `ok`, all 5 m and 180° off, exit 0) hides the landmarks where the scanner sees them and
/// shows them where it cannot. None otherwise.
pub fn facings_hide_poses(
    loc: &Localizer,
    scans: &[Scan],
    rate_hz: f64,
    global_only: bool,
    given: &PoseLog,
) -> Option<FacingsOff> {
    let free = Localizer::new(loc.map.without_facings()?, loc.cfg);
    let scans = &scans[..scans.len().min(MIRROR_PROBE_SCANS)];
    let n_ok_given = given
        .rows
        .iter()
        .take(scans.len())
        .filter(|r| r.status == Status::Ok && r.pose.is_some())
        .count();
    let run = localize_scans(&free, scans, rate_hz, global_only, &|| {});
    let poses: Vec<_> = run
        .log
        .rows
        .iter()
        .filter(|r| r.status == Status::Ok)
        .filter_map(|r| r.pose)
        .collect();
    let n = scans.len();
    if (poses.len() as f64) < MIN_SHARE_OK * n as f64 || poses.len() < n_ok_given {
        return None;
    }
    let range_m = loc.cfg.sensor.max_range_m;
    let (mut sin, mut cos) = (0.0f64, 0.0f64);
    for p in &poses {
        let at = nalgebra::Point2::new(p.x_m, p.y_m);
        for l in &loc.map.landmarks {
            let (Some(f), v) = (l.facing, at - l.position) else {
                continue;
            };
            if v.norm() > range_m || loc.map.occluded(&at, &l.position, 0.05) {
                continue;
            }
            let a = f.perp(&v).atan2(f.dot(&v));
            sin += a.sin();
            cos += a.cos();
        }
    }
    // A circular mean: the angles of facings reversed lie either side of ±π.
    let offset_rad = sin.atan2(cos);
    (offset_rad.abs() > MAX_FACING_OFFSET_RAD).then_some(FacingsOff {
        n_scans: n,
        n_ok_given,
        n_ok_free: poses.len(),
        offset_rad,
    })
}
