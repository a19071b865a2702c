//! `odocal synth calib`: checkerboard or ChArUco views and floor views from a known camera.

use std::path::{Path, PathBuf};

use clap::Args as ClapArgs;
use odocal_calib::charuco::MIN_MARKER_SIDE_PX;
use odocal_calib::{CameraFile, LensModel};
use odocal_synth::board::{
    calibration_errors, floor_error_over_sigma, lens_preset, median_marker_side_px,
    typical_hfov_deg, visible_share, vouched_floor_error, CalibScene, CalibTruth, FLOOR_RINGS_DEG,
};
use odocal_synth::calib_set::{self, check_scene};

use super::board::{TargetArg, TargetArgs};
use crate::output::{commit, count, progress, synth_out_dir};

/// Arguments of `odocal synth calib`.
#[derive(ClapArgs)]
pub struct Args {
    /// Output folder (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Number of hand-held board views.
    #[arg(long, default_value_t = 20)]
    views: usize,
    /// Number of views of the board lying on the floor.
    #[arg(long, default_value_t = 4)]
    floor_views: usize,
    /// Random seed (same seed, same bytes).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Image width, pixels.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Horizontal field of view, degrees (edge to edge through the image centre) [default:
    /// the lens's own: 70 (pinhole5), 110 (rational), 150 (fisheye)].
    #[arg(long)]
    hfov: Option<f64>,
    /// The true lens: pinhole5 (a 70° lens, OpenCV's five coefficients), rational (a strong
    /// barrel lens, ~110°) or fisheye (Kannala–Brandt, ~150°).
    #[arg(long, default_value = "pinhole5")]
    lens: String,
    /// Sensor noise σ, grey levels.
    #[arg(long, default_value_t = 2.0)]
    noise: f32,
    /// Optical blur σ, pixels.
    #[arg(long, default_value_t = 0.5)]
    blur: f32,
    /// Board size, COLSxROWS: a checkerboard's inner corners (default 9x6), a ChArUco board's
    /// squares (default 11x8).
    #[arg(long)]
    board: Option<String>,
    /// Board square size, metres [default: 0.05 (checkerboard) or 0.04 (ChArUco) with the
    /// pinhole5 lens; 0.08 with the wide lenses (0.12 for a ChArUco board and the fisheye),
    /// whose floor views at 2.2 m would otherwise show squares and markers too small to measure].
    #[arg(long)]
    square: Option<f64>,
    /// The board (ChArUco defaults: markers 0.75 of the square, of 4X4_50).
    #[command(flatten)]
    target: TargetArgs,
}

/// Renders a calibration session into `out` (staged: it appears when the command succeeds).
pub fn write_calib_set(out: &Path, scene: &CalibScene, seed: u64) -> anyhow::Result<CalibTruth> {
    check_scene(scene)?;
    let dir = synth_out_dir(out, "--out")?;
    let bar = progress((scene.views + scene.floor_views) as u64, "rendering");
    let truth = calib_set::write_calib_set(&dir, scene, seed, &|| bar.inc(1));
    bar.finish_and_clear();
    Ok(truth?)
}

/// Runs `odocal synth calib`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let lens = LensModel::parse(&a.lens).ok_or_else(|| {
        anyhow::anyhow!(
            "--lens {:?} is not a lens model: use pinhole5, rational or fisheye",
            a.lens
        )
    })?;
    super::synth_count_at_most(a.views, "--views", 500, "views of a calibration")?;
    super::synth_count_at_most(a.floor_views, "--floor-views", 100, "floor views")?;
    let hfov = a.hfov.unwrap_or(typical_hfov_deg(lens));
    let charuco = a.target.target == TargetArg::Charuco;
    let square = a.square.unwrap_or(match (charuco, lens) {
        (true, LensModel::Pinhole5) => 0.04,
        (true, LensModel::Rational) => 0.08,
        // Through a 150° fisheye an 8 cm ChArUco square on the floor 2.2 m below is 18 px
        // wide, its corners 2 px from the markers: the floor plane comes out ~1 mm uncertain.
        (true, LensModel::Fisheye) => 0.12,
        (false, LensModel::Pinhole5) => 0.05,
        (false, _) => 0.08,
    });
    let board = a.target.board_spec(
        a.board.as_deref(),
        square,
        "9x6",
        Some(("11x8", 0.75 * square, "4X4_50")),
    )?;
    let scene = CalibScene {
        distortion: lens_preset(lens),
        width: a.width,
        height: a.height,
        hfov_deg: hfov,
        board,
        views: a.views,
        floor_views: a.floor_views,
        noise_sigma: a.noise,
        blur_px: a.blur,
        ..CalibScene::default()
    };
    let truth = write_calib_set(&a.out, &scene, a.seed)?;
    commit()?;
    if truth.floor_views.len() < scene.floor_views {
        tell!(
            "warning: only {} of the {} floor views asked for hold a whole board in the {}x{} image of a {}° camera {} m up: the floor plane rests on those; give a wider --hfov or a smaller --square for all of them",
            truth.floor_views.len(),
            scene.floor_views,
            a.width,
            a.height,
            hfov,
            scene.camera_height_m
        );
    }
    let floor_poses: Vec<_> = truth
        .floor_views
        .iter()
        .map(|v| v.board_to_camera)
        .collect();
    let marker_px = median_marker_side_px(&truth.camera, &floor_poses, &scene.board);
    if let Some(side) = marker_px.filter(|side| *side < MIN_MARKER_SIDE_PX) {
        // Larger squares make larger markers; round the advice up to the next centimetre.
        let enough_m = (scene.board.square_m * MIN_MARKER_SIDE_PX / side * 100.0).ceil() / 100.0;
        tell!(
            "warning: the floor views' markers are {side:.0} px across (median), fewer than the {MIN_MARKER_SIDE_PX:.0} px `calibrate` needs to place the corners between them, so it will not fix the floor from them; give --square {enough_m} or more (the markers scale with it) or a higher resolution"
        );
    }
    let k = truth.camera.intrinsics;
    if scene.board.is_charuco() {
        say!(
            "wrote {} and {} ({}x{}, {}) to {}",
            count(truth.views.len(), "board view"),
            count(truth.floor_views.len(), "floor view"),
            a.width,
            a.height,
            scene.board,
            a.out.display()
        );
        let shares: Vec<f64> = truth
            .views
            .iter()
            .map(|v| visible_share(&truth.camera, &v.board_to_camera, &scene.board))
            .collect();
        let partly = shares.iter().filter(|&&s| s < 1.0).count();
        let third = shares.iter().filter(|&&s| s <= 2.0 / 3.0).count();
        let least = shares.iter().copied().fold(1.0, f64::min);
        say!(
            "board partly outside the image in {partly} of {} views, a third or more outside in {third}; least in view: {:.0} % of the inner corners",
            shares.len(),
            least * 100.0
        );
    } else {
        say!(
            "wrote {} and {} ({}x{}, board {}x{} inner corners, {} m squares) to {}",
            count(truth.views.len(), "board view"),
            count(truth.floor_views.len(), "floor view"),
            a.width,
            a.height,
            scene.board.cols,
            scene.board.rows,
            scene.board.square_m,
            a.out.display()
        );
    }
    say!(
        "true camera: {} lens, {:.0}° across, fx {:.2} px, fy {:.2} px, cx {:.2} px, cy {:.2} px (truth.json, camera_true.json)",
        lens, hfov, k.fx, k.fy, k.cx, k.cy
    );
    Ok(())
}

/// How many of the calibration's own σ an intrinsic's error may reach: beyond, its ± are
/// not honest.
const CHECK_SIGMAS: f64 = 3.0;

/// The floor's error over its σ (RMS over the vouched pixels) beyond which the check fails:
/// an honest σ gives 1 to 1.4 (√2, its worst direction), and the pixels of one smooth map
/// are not independent, so a margin is left over that.
const FLOOR_SIGMA_UNDERSTATED: f64 = 2.0;

/// Arguments of `odocal synth check-calib`.
#[derive(ClapArgs)]
pub struct CheckArgs {
    /// camera.json written by `odocal calibrate`.
    #[arg(long)]
    camera: PathBuf,
    /// truth.json written by `odocal synth calib`.
    #[arg(long)]
    truth: PathBuf,
}

/// Runs `odocal synth check-calib`: the calibration's error against the truth.
pub fn run_check(a: CheckArgs) -> anyhow::Result<()> {
    let cam = CameraFile::load(&a.camera)?;
    // The floor frame is the one the first floor view given to `calibrate` fixes: another
    // view given first put a right calibration 1.7 m off.
    let truth = CalibTruth::read_for_file(&a.truth, &cam)?;
    let e = calibration_errors(
        &cam.camera,
        cam.floor.as_ref().map(|f| &f.floor_to_camera),
        &truth.camera,
        &truth.floor_to_camera,
    );
    // Each intrinsic's error in its own σ: the fixed bounds ask more of a small image or a
    // few views than their corners can give (7 of 8 honest 640x360 calibrations of 8 views
    // failed them, every error within 1.8σ).
    let sd = cam.std.clone();
    let t = truth.camera.intrinsics;
    let sigmas: Vec<Option<f64>> = [
        (e.fx_rel * t.fx, sd.as_ref().map(|s| s.fx)),
        (e.fy_rel * t.fy, sd.as_ref().map(|s| s.fy)),
        (e.cx_px, sd.as_ref().map(|s| s.cx)),
        (e.cy_px, sd.as_ref().map(|s| s.cy)),
    ]
    .into_iter()
    .map(|(err, s)| s.filter(|s| *s > 0.0 && s.is_finite()).map(|s| err / s))
    .collect();
    let in_sigma = |k: usize| sigmas[k].map(|z| format!(" ({z:.1}σ)")).unwrap_or_default();
    say!(
        "calibration error against the truth: fx {:.3} %{}, fy {:.3} %{}, cx {:.2} px{}, cy {:.2} px{} (bounds 0.2 %, 0.2 %, 1 px, 1 px; σ: the calibration's own)",
        e.fx_rel * 100.0,
        in_sigma(0),
        e.fy_rel * 100.0,
        in_sigma(1),
        e.cx_px,
        in_sigma(2),
        e.cy_px,
        in_sigma(3)
    );
    let names = ["fx", "fy", "cx", "cy"];
    let beyond_sigma: Vec<String> = names
        .iter()
        .zip(&sigmas)
        .filter_map(|(n, z)| {
            z.filter(|z| *z > CHECK_SIGMAS)
                .map(|z| format!("{n} {z:.1}σ"))
        })
        .collect();
    match (e.floor_max_m, e.floor_rms_m, e.floor_reach_m) {
        (Some(max), Some(rms), Some(reach)) => say!(
            "floor mapping error over all the floor the image sees (out to {reach:.2} m from the point under the camera): {:.2} mm RMS, {:.2} mm max (bound 2 mm)",
            rms * 1e3,
            max * 1e3
        ),
        _ => say!("no floor plane in {}", a.camera.display()),
    }
    let mut lo = 0.0;
    for (r, max) in FLOOR_RINGS_DEG.iter().zip(&e.floor_max_by_ring_m) {
        if let Some(m) = max {
            say!(
                "  floor seen {lo:.0}-{r:.0}° off the nadir: largest mapping error {:.2} mm",
                m * 1e3
            );
        }
        lo = *r;
    }
    let vouched = vouched_floor_error(&cam, &truth);
    if let Some((reach, max)) = vouched {
        say!(
            "  floor `calibrate` vouches for ({} mm at {}σ: out to {:.2} m from the point under the camera, {:.0}° off the nadir): largest mapping error {:.2} mm",
            odocal_calib::FLOOR_BOUND_MM,
            odocal_calib::FLOOR_BOUND_SIGMAS,
            reach.radius_m,
            reach.off_nadir_deg,
            max * 1e3
        );
    }
    // The floor's σ judged where `calibrate` vouches for the floor: the vouched bound is a
    // multiple of σ, so a σ too small vouches for floor it does not know.
    let mut sigma_understated: Option<String> = None;
    if let Some((z, n)) = floor_error_over_sigma(&cam, &truth, None) {
        // Beyond the floor vouched for, the lens model is extrapolated, and σ (how well the
        // model's parameters are known) does not say how far the model is from the lens.
        let vouched_z = match vouched {
            Some((reach, _)) if !reach.whole => {
                floor_error_over_sigma(&cam, &truth, Some(reach.radius_m))
            }
            Some(_) => Some((z, n)),
            None => None,
        };
        if let Some((zv, nv)) = vouched_z.filter(|(zv, _)| *zv > FLOOR_SIGMA_UNDERSTATED) {
            sigma_understated = Some(format!(
                "the floor mapping error is {zv:.2} times the floor map's σ (RMS over the {nv} pixels where `calibrate` vouches for the floor; 1 to 1.4 when σ is honest, failed beyond {FLOOR_SIGMA_UNDERSTATED}): the σ understates the error, and the floor is vouched for farther than it is known"
            ));
        }
        let vouched_part = vouched
            .filter(|(reach, _)| !reach.whole)
            .and(vouched_z)
            .map(|(z, n)| format!("; over the {n} where `calibrate` vouches for the floor: {z:.2}"))
            .unwrap_or_default();
        say!(
            "  floor mapping error over the floor map's σ (its worst direction), RMS over {n} pixels: {z:.2}{vouched_part} (1 to 1.4 when σ is honest; under 1, σ too large)"
        );
    }
    let mut failed = e.failures(vouched.map(|(_, max)| max));
    failed.extend(sigma_understated);
    // An intrinsic outside its fixed bound but within 3σ is as good as the views allow, and
    // says so; one outside both is off by more than the calibration claims.
    let (honest, failed): (Vec<String>, Vec<String>) = failed.into_iter().partition(|f| {
        names
            .iter()
            .position(|n| f.starts_with(&format!("{n} error")))
            .and_then(|k| sigmas[k])
            .is_some_and(|z| z <= CHECK_SIGMAS)
    });
    let understated = (!beyond_sigma.is_empty()).then(|| {
        format!(
            "off by more than {CHECK_SIGMAS:.0}σ of the calibration's own σ ({}): its ± understate the error",
            beyond_sigma.join(", ")
        )
    });
    if !honest.is_empty() {
        say!(
            "  outside the fixed bounds but within {CHECK_SIGMAS:.0}σ of the calibration's own σ, so not failed (the views allow no better; more views, or views filling more of the image, tighten it): {}",
            honest.join("; ")
        );
    }
    if !failed.is_empty() {
        anyhow::bail!(
            "{} fails the check against {}: {}{}",
            a.camera.display(),
            a.truth.display(),
            failed.join("; "),
            understated.map(|u| format!("; {u}")).unwrap_or_default()
        );
    }
    if let Some(u) = understated {
        tell!("warning: {u}");
    }
    say!(
        "check passed: fx, fy within 0.2 %, cx, cy within 1 px{}{}",
        if honest.is_empty() {
            ""
        } else {
            " or within 3σ of the calibration's own σ"
        },
        match (vouched, e.floor_max_by_ring_m[0]) {
            (Some(_), _) => ", floor within 2 mm where calibrate vouches for it",
            (None, Some(_)) =>
                ", floor within 2 mm within 30° of the nadir (the camera file vouches for no floor)",
            (None, None) => "",
        }
    );
    Ok(())
}
