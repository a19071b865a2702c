//! Shared views: one board lying on the floor, photographed at the same moment by every camera
//! that sees it. Images are named `<view>_c<K>.<ext>`, K the camera's place (from 0) in the
//! list of camera files, so all images of one view share `<view>`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use odocal_calib::{detect_file, BoardSpec, BoardView, Detection};
use rayon::prelude::*;

use crate::ArenaError;

/// One shared view: the board as each camera that found it saw it.
#[derive(Debug, Clone, PartialEq)]
pub struct SharedView {
    /// The view's name (the file names' common part).
    pub name: String,
    /// (camera index, the detected board), cameras in increasing order.
    pub views: Vec<(usize, BoardView)>,
}

/// Splits `s03_c1.png` into ("s03", 1); the message says what was expected.
pub fn parse_shared_name(path: &Path, cameras: usize) -> Result<(String, usize), ArenaError> {
    let bad = |why: &str| {
        ArenaError::Input(format!(
            "{}: {why}; shared views are named VIEW_cK.png, K the camera's place (0..{}) in --camera",
            path.display(),
            cameras.saturating_sub(1)
        ))
    };
    let stem = path
        .file_stem()
        .and_then(|s| s.to_str())
        .ok_or_else(|| bad("the name is not text"))?;
    let (view, cam) = stem
        .rsplit_once("_c")
        .ok_or_else(|| bad("the name does not end in _cK"))?;
    let k: usize = cam
        .parse()
        .map_err(|_| bad(&format!("{cam:?} after _c is not a camera number")))?;
    if k >= cameras {
        return Err(bad(&format!(
            "camera {k} does not exist ({cameras} camera files given)"
        )));
    }
    if view.is_empty() {
        return Err(bad("the view's name before _cK is empty"));
    }
    Ok((view.to_string(), k))
}

/// Expands folders into their PNG/JPEG files (sorted), keeps files as given.
fn expand(paths: &[PathBuf]) -> Result<Vec<PathBuf>, ArenaError> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let rd = std::fs::read_dir(p).map_err(|e| {
                ArenaError::Input(format!("{}: cannot list the folder: {e}", p.display()))
            })?;
            let mut files: Vec<PathBuf> = rd
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| {
                    f.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                        ["png", "jpg", "jpeg"].contains(&e.to_ascii_lowercase().as_str())
                    })
                })
                .collect();
            files.sort();
            out.extend(files);
        } else if p.exists() {
            out.push(p.clone());
        } else {
            return Err(ArenaError::Input(format!(
                "--shared {}: no such file or folder; give the shared views' images, or the folder that holds them",
                p.display()
            )));
        }
    }
    Ok(out)
}

/// Finds the board in every shared image (folders are read for their PNG/JPEG files) and
/// groups the images by view. A camera's image without the board is left out with a note;
/// views with the board in fewer than two cameras tie nothing and are left out with a note.
pub fn detect_shared(
    paths: &[PathBuf],
    cameras: usize,
    board: &BoardSpec,
    sizes: &[(u32, u32)],
) -> Result<(Vec<SharedView>, Vec<String>), ArenaError> {
    let files = expand(paths)?;
    if files.is_empty() {
        return Err(ArenaError::Input(
            "no shared views: give --shared images of a board on the floor seen by two cameras at once".into(),
        ));
    }
    let named = files
        .iter()
        .map(|f| parse_shared_name(f, cameras).map(|(v, k)| (f.clone(), v, k)))
        .collect::<Result<Vec<_>, _>>()?;
    // A --board typo costs the classic detector tens of seconds per image, and the arena
    // then misreads the corners it finds: the first image is looked at quickly first.
    if let Some(seen) = named
        .first()
        .filter(|(f, ..)| odocal_calib::charuco::markers_seen(f).is_none())
        .and_then(|(f, ..)| odocal_calib::detect::quick_board_size_check(f, board))
    {
        return Err(ArenaError::Input(seen.refusal(&named[0].0, board)));
    }
    let mut detections = named
        .iter()
        .take(1)
        .map(|(f, v, k)| detect_file(f, board).map(|d| (v.clone(), *k, d)))
        .collect::<Result<Vec<_>, _>>()?;
    // A --board short of the real one finds part of the board, a different part in each
    // camera, which the arena then read as cameras 75 mm apart.
    if let Some((_, _, Detection::Found(first))) = detections.first() {
        let larger = (!board.is_charuco())
            .then(|| {
                odocal_calib::detect::larger_board_around(
                    Path::new(&first.image),
                    board,
                    &first.corners,
                )
            })
            .flatten();
        if let Some(size) = larger {
            let (c, r) = odocal_calib::detect::oriented_like(size, board);
            return Err(ArenaError::Input(format!(
                "{} shows a board of at least {c}x{r} inner corners, but --board {}x{} finds only part of it (a different part in each camera, which puts the cameras apart by squares): count the board's INNER corners (one fewer than the squares along each side) and pass them as --board",
                first.image, board.cols, board.rows
            )));
        }
    }
    detections.extend(
        named
            .par_iter()
            .skip(1)
            .map(|(f, v, k)| detect_file(f, board).map(|d| (v.clone(), *k, d)))
            .collect::<Result<Vec<_>, _>>()?,
    );
    let mut notes = Vec::new();
    let mut by_view: BTreeMap<String, Vec<(usize, BoardView)>> = BTreeMap::new();
    for (view, k, d) in detections {
        match d {
            Detection::Found(bv) => {
                if bv.size != sizes[k] {
                    return Err(ArenaError::Input(format!(
                        "{}: {}x{} pixels, but camera {k}'s file describes {}x{} images; is _c{k} the right camera?",
                        bv.image, bv.size.0, bv.size.1, sizes[k].0, sizes[k].1
                    )));
                }
                let list = by_view.entry(view.clone()).or_default();
                if list.iter().any(|(c, _)| *c == k) {
                    return Err(ArenaError::Input(format!(
                        "{}: view {view} has two images from camera {k}",
                        bv.image
                    )));
                }
                list.push((k, bv));
            }
            Detection::NotFound { image, .. } => {
                notes.push(format!(
                    "skipped {image}: no {}x{} board found",
                    board.cols, board.rows
                ));
            }
        }
    }
    let mut views = Vec::new();
    for (name, mut list) in by_view {
        if list.len() < 2 {
            notes.push(format!(
                "skipped view {name}: the board was found by only one camera"
            ));
            continue;
        }
        list.sort_by_key(|(k, _)| *k);
        views.push(SharedView { name, views: list });
    }
    Ok((views, notes))
}

/// How far a camera's height above a shared board may differ from its calibrated height
/// above the floor before the board's square is taken for the wrong size (a board lying on
/// the floor puts the camera at its floor height; a wrong `--square` scales it).
const SCALE_TOLERANCE: f64 = 0.15;

/// Refuses a board side that the shared views contradict, before the arena is solved (whose
/// search with a wrong side takes minutes, then fails as if cameras were out of place): the
/// first view of each camera with a calibrated floor, located with `board`, puts the camera at
/// its floor height only when the side is right.
pub fn check_board_scale(
    files: &[odocal_calib::CameraFile],
    shared: &[SharedView],
    board: &BoardSpec,
) -> Result<(), ArenaError> {
    // (camera, its first shared view, height above the board, height above the floor)
    let mut heights = Vec::new();
    for (k, file) in files.iter().enumerate() {
        let Some(floor) = &file.floor else { continue };
        let Some(view) = shared
            .iter()
            .find_map(|s| s.views.iter().find(|(c, _)| *c == k).map(|(_, v)| v))
        else {
            continue;
        };
        let Ok(pose) = odocal_calib::board_pose(&file.camera, view, board) else {
            continue;
        };
        // The camera's distance from the board's plane, in the board's frame.
        let above_m = pose.0.inverse().translation.vector.z.abs();
        heights.push((k, view, above_m, floor.camera_height_m));
    }
    if heights.is_empty() {
        return Ok(());
    }
    // A wrong side scales every camera alike; a camera whose calibration is another
    // camera's is off alone. Judged against the median camera: a side "fitting" the odd
    // camera only moved the refusal to the others.
    let mut ratios: Vec<f64> = heights.iter().map(|h| h.2 / h.3).collect();
    ratios.sort_by(f64::total_cmp);
    let median = ratios[ratios.len() / 2];
    let apart = |a: f64, b: f64| (a / b - 1.0).abs() > SCALE_TOLERANCE;
    let odd = heights.iter().find(|h| apart(h.2 / h.3, median));
    let name_odd = |&(k, view, above_m, height_m): &(usize, &BoardView, f64, f64)| {
        format!(
            "{}: the board puts camera {k} {above_m:.2} m above it, where its calibration's floor puts it {height_m:.2} m up, unlike the other cameras: camera {k}'s camera.json is not of this camera (or the camera was refocused or moved after calibration); give the camera.json calibrated for it",
            view.image
        )
    };
    if !apart(median, 1.0) {
        return match odd {
            Some(h) => Err(ArenaError::Input(name_odd(h))),
            None => Ok(()),
        };
    }
    let Some(&(k, view, above_m, height_m)) = heights.iter().find(|h| !apart(h.2 / h.3, median))
    else {
        return Ok(());
    };
    let also = odd.map_or(String::new(), |h| format!("; and {}", name_odd(h)));
    Err(ArenaError::Input(format!(
        "{}: with squares of {} m the board puts camera {k} {above_m:.2} m above it, where its calibration's floor puts it {height_m:.2} m up (as it does the other cameras, scaled alike); a board on the floor with those corners has squares of {:.3} m: give --square {:.3} (or leave --square out if the shared board is the one the cameras were calibrated with){also}",
        view.image,
        board.square_m,
        board.square_m / median,
        board.square_m / median
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_names_give_view_and_camera() {
        let ok = parse_shared_name(Path::new("d/s_03_c2.png"), 4).unwrap();
        assert_eq!(ok, ("s_03".to_string(), 2));
        for (name, why) in [
            ("d/s03.png", "does not end in _cK"),
            ("d/s03_cx.png", "is not a camera number"),
            ("d/s03_c4.png", "camera 4 does not exist"),
            ("d/_c1.png", "is empty"),
        ] {
            let e = parse_shared_name(Path::new(name), 4)
                .unwrap_err()
                .to_string();
            assert!(e.contains(why) && e.contains("VIEW_cK"), "{name}: {e}");
        }
    }
}
