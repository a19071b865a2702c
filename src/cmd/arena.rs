//! `odocal arena`: several calibrated cameras in one floor frame, tied together by boards
//! lying on the floor where their views overlap, photographed by both cameras at once.

use std::path::{Path, PathBuf};

use anyhow::bail;
use odocal_arena::{
    build_arena, check_board_scale, detect_shared, height_warnings, shared_residual_warnings,
};
use odocal_calib::{BoardSpec, CameraFile};

use crate::output::{check_output_file, check_output_not_in_folder, commit, write_json};

/// Arguments of `odocal arena`.
#[derive(clap::Args)]
pub struct Args {
    /// camera.json of every camera (from `odocal calibrate`); the first, calibrated with
    /// --floor, fixes the arena's floor frame.
    #[arg(long, num_args = 2.., required = true)]
    pub camera: Vec<PathBuf>,
    /// Shared views (files or folders): a board lying on the floor, photographed at once by
    /// two or more cameras, named VIEW_cK.png with K the camera's place (from 0) in --camera.
    #[arg(long, num_args = 1.., required = true)]
    pub shared: Vec<PathBuf>,
    /// Board size in inner corners, COLSxROWS (default: the first camera file's board).
    #[arg(long)]
    pub board: Option<String>,
    /// Side of one square, metres (default: the first camera file's board).
    #[arg(long)]
    pub square: Option<f64>,
    /// Where to write the arena file (`odocal.arena/1`).
    #[arg(long)]
    pub out: PathBuf,
}

fn board_of(args: &Args, first: &CameraFile) -> anyhow::Result<BoardSpec> {
    Ok(match (&args.board, args.square, first.board) {
        (Some(b), Some(s), _) => BoardSpec::parse(b, s)?,
        (None, None, Some(b)) => b,
        (Some(b), None, Some(fb)) => BoardSpec::parse(b, fb.square_m)?,
        (None, Some(s), Some(fb)) => BoardSpec::parse(&format!("{}x{}", fb.cols, fb.rows), s)?,
        _ => bail!(
            "{} names no board: give --board COLSxROWS and --square METRES of the shared views' board",
            args.camera[0].display()
        ),
    })
}

/// Runs `odocal arena`.
pub fn run(args: Args) -> anyhow::Result<()> {
    check_output_file(&args.out, "--out")?;
    check_output_not_in_folder(&args.out, "--out", &args.shared, "--shared")?;
    let files = args
        .camera
        .iter()
        .map(|p| CameraFile::load(p))
        .collect::<Result<Vec<_>, _>>()?;
    // One calibration given for two cameras still fits the shared boards to a millimetre,
    // with that camera placed centimetres off: refused by path and by content.
    for (j, b) in files.iter().enumerate() {
        if let Some(i) = files[..j].iter().position(|a| a == b) {
            anyhow::bail!(
                "--camera: cameras {i} ({}) and {j} ({}) have the same calibration: give each camera its own camera.json, in the order of the _cK shared views",
                args.camera[i].display(),
                args.camera[j].display()
            );
        }
    }
    let board = board_of(&args, &files[0])?;
    let sizes: Vec<(u32, u32)> = files
        .iter()
        .map(|f| (f.camera.width, f.camera.height))
        .collect();
    let (shared, notes) = detect_shared(&args.shared, files.len(), &board, &sizes)?;
    for n in &notes {
        tell!("note: {n}");
    }
    check_board_scale(&files, &shared, &board)?;
    let paths: Vec<&Path> = args.camera.iter().map(|p| p.as_path()).collect();
    // A board side other than the one the cameras were calibrated with scales every shared
    // board's distance: the failure reads as cameras or views out of place, so the side is
    // named with it.
    let calibrated = files[0].board.map(|b| b.square_m);
    let (arena, solution) = build_arena(&files, &paths, &shared, &board).map_err(|e| {
        match (args.square, calibrated) {
            (Some(s), Some(c)) if (s / c - 1.0).abs() > 1e-6 => anyhow::anyhow!(
                "{e}; --square {s} m is not the {c} m of the board the cameras were calibrated with: if the shared views show that board, leave --square out"
            ),
            _ => e.into(),
        }
    })?;
    // Each calibration's error reaches every camera tied to it through the shared boards;
    // a file without its covariance (an export, or an older odocal) drops that part of
    // every fused σ.
    let files_where = |skip: usize, pred: &dyn Fn(&CameraFile) -> bool| -> Vec<String> {
        files
            .iter()
            .zip(&args.camera)
            .skip(skip)
            .filter(|(f, _)| pred(f))
            .map(|(_, p)| p.display().to_string())
            .collect()
    };
    let bare = files_where(0, &|f| f.covariance.is_none());
    if !bare.is_empty() {
        tell!(
            "note: {} carr{} no covariance of the intrinsics: the σ of fixes fused through this arena will leave out {} calibration error, which reaches every camera tied to {} through the shared boards; calibrate with `odocal calibrate` (its camera files carry it) for σ that include it",
            bare.join(", "),
            if bare.len() == 1 { "ies" } else { "y" },
            if bare.len() == 1 { "its" } else { "their" },
            if bare.len() == 1 { "it" } else { "them" },
        );
    }
    // Without its own floor views a camera's height cannot be checked: another camera's
    // calibration of a like lens fits the shared boards as well, its focal length traded for
    // height (5.8 % too high on the synthetic arena, seeds 1–3, with no other sign).
    let unchecked = files_where(1, &|f| f.floor.is_none());
    if !unchecked.is_empty() {
        tell!(
            "note: {} {} no floor views, so the camera's height in the arena cannot be checked against {} own: a calibration of another camera with a like lens would pass unnoticed, its camera placed a few % too high or low; calibrate every camera with --floor to have it checked",
            unchecked.join(", "),
            if unchecked.len() == 1 { "has" } else { "have" },
            if unchecked.len() == 1 { "its" } else { "their" },
        );
    }
    for (r, &camera) in solution
        .renumbered
        .iter()
        .flat_map(|r| r.cameras.iter().map(move |c| (r, c)))
    {
        tell!(
            "note: camera {} ({}): its shared images number the board's corners from the other end, as images turned about 180° from the first camera's do (OpenCV numbers a checkerboard's corners from the one nearest the image's top-left): as numbered the cameras put the shared corners {:.1} mm apart (RMS), so they were read with that camera's numbering turned back, and agree within {:.2} mm; a camera mounted turned needs nothing more, and a ChArUco board (--target charuco) names its corners alike in every camera",
            camera,
            paths[camera].display(),
            r.numbered_as_recorded_mm,
            solution.consistency.rms_mm
        );
    }
    let heights = height_warnings(&files, &paths, &solution.arena_to_camera)?;
    for w in shared_residual_warnings(&files, &paths, &solution.rms_px)
        .into_iter()
        .chain(heights)
    {
        tell!("warning: {w}");
    }
    // `track` checks every arena file it reads: one it would refuse is not written.
    if let Err(e) = arena.check() {
        bail!(
            "the arena solved from these camera files is not plausible ({e}); check the camera files and the shared views"
        );
    }
    write_json(&args.out, &arena)?;
    for (k, c) in arena.cameras.iter().enumerate() {
        let at = c.arena_to_camera.0.inverse().translation.vector;
        say!(
            "camera {k} ({}): at ({:.3}, {:.3}) m, {:.3} m above the floor; {} shared views, corner residual {:.3} px RMS",
            c.source, at.x, at.y, at.z, c.shared_views, c.rms_px
        );
    }
    for p in &arena.pairs {
        say!(
            "cameras {} and {}: the same floor point {:.2} mm apart RMS, {:.2} mm at most ({} corners)",
            p.cameras.0,
            p.cameras.1,
            p.consistency.rms_mm,
            p.consistency.max_mm,
            p.consistency.points
        );
    }
    let c = &arena.consistency;
    say!(
        "consistency in the overlaps: {:.2} mm RMS, {:.2} mm max over {} corners of {} shared views",
        c.rms_mm,
        c.max_mm,
        c.points,
        arena.shared_views.len()
    );
    match &arena.frame_placement {
        Some(f) => {
            // The camera farthest from the origin sees the frame's turn the most.
            let (far_k, far) = arena
                .cameras
                .iter()
                .map(|c| {
                    let at = c.arena_to_camera.0.inverse().translation.vector;
                    nalgebra::Point2::new(at.x, at.y)
                })
                .enumerate()
                .max_by(|a, b| a.1.coords.norm().total_cmp(&b.1.coords.norm()))
                .unwrap_or((0, nalgebra::Point2::origin()));
            let origin = f.origin_sigma_m();
            say!(
                "floor frame (camera 0's floor boards): heading σ {:.3} mrad, origin σ {:.2} mm (x) {:.2} mm (y), {:.2} mm under camera {far_k} ({:.1} m out): a turn and shift of every fix alike, part of the fixes' σ; a run aligned to its odometry takes it up",
                f.heading_sigma_rad() * 1e3,
                origin.x * 1e3,
                origin.y * 1e3,
                f.sigma_at_m(&far) * 1e3,
                far.coords.norm()
            );
        }
        // A file without the intrinsics' covariance is named above; one that has it but not
        // the floor's was written by an odocal that did not keep it.
        None if files[0].covariance.is_some() => tell!(
            "warning: {} keeps no covariance of its floor (calibrated before camera files kept it), so the fixes' σ leave out how well the floor frame itself is placed, most of their error on a small arena; calibrate camera 0 again with `odocal calibrate` to have it",
            paths[0].display()
        ),
        None => {}
    }
    commit()?;
    say!("wrote {}", args.out.display());
    Ok(())
}
