//! The floor plane: boards lying flat on the floor, each located by solvePnP,
//! one plane fitted through all their corners. The first floor view fixes the
//! floor frame's origin (its first inner corner; for a ChArUco board corner 0, whether or
//! not it is in view) and x axis (along its rows); z points up, towards the camera.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use opencv::calib3d;

use crate::opencv_glue::solve_pnp;
use crate::{
    BoardSpec, BoardToCamera, BoardView, CalibError, CameraModel, FloorPlane, FloorToCamera,
};

/// Locates one board in the camera frame with a calibrated camera, from the view's corners
/// and their places on the board (all corners of a checkerboard, those found of a ChArUco
/// board; `board` names it in errors).
pub fn board_pose(
    camera: &CameraModel,
    view: &BoardView,
    board: &BoardSpec,
) -> Result<BoardToCamera, CalibError> {
    if view.object_points.len() != view.corners.len() || view.corners.len() < 4 {
        return Err(CalibError::Input(format!(
            "{}: {} corners of the {} with {} board positions; locating it needs at least 4",
            view.image,
            view.corners.len(),
            crate::charuco::board_name(board),
            view.object_points.len()
        )));
    }
    match solve_pnp(
        camera,
        &view.object_points,
        &view.corners,
        calib3d::SOLVEPNP_ITERATIVE,
    )? {
        Some(iso) => Ok(BoardToCamera(iso)),
        None => Err(CalibError::Input(format!(
            "{}: cannot locate the floor board",
            view.image
        ))),
    }
}

/// Fits the floor plane through the boards of all floor views.
pub fn fit_floor(
    camera: &CameraModel,
    views: &[BoardView],
    board: &BoardSpec,
) -> Result<FloorPlane, CalibError> {
    if views.is_empty() {
        return Err(CalibError::Input(
            "no floor view: lay the board flat on the floor and photograph it".into(),
        ));
    }
    let poses = views
        .iter()
        .map(|v| board_pose(camera, v, board))
        .collect::<Result<Vec<_>, _>>()?;
    plane_from_poses(&poses, views)
}

/// The floor plane through boards lying on the floor, located at `poses` (one per view):
/// the least-squares plane of all their corners, its origin at the first board's first
/// corner and its x axis along that board's rows.
pub(crate) fn plane_from_poses(
    poses: &[BoardToCamera],
    views: &[BoardView],
) -> Result<FloorPlane, CalibError> {
    let mut pts: Vec<Point3<f64>> = Vec::new();
    for (pose, v) in poses.iter().zip(views) {
        pts.extend(v.object_points.iter().map(|p| pose.0 * p));
    }
    let Some(&first_pose) = poses.first() else {
        return Err(CalibError::Input("no floor view".into()));
    };
    if !pts.iter().all(|p| p.coords.iter().all(|v| v.is_finite())) {
        return Err(CalibError::Input(
            "a floor board could not be located (its pose is not finite)".into(),
        ));
    }
    let n = pts.len() as f64;
    let centroid = pts.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n;
    let mut scatter = Matrix3::zeros();
    for p in &pts {
        let d = p.coords - centroid;
        scatter += d * d.transpose();
    }
    let eig = scatter.symmetric_eigen();
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |b, (i, &v)| if v < b.1 { (i, v) } else { b },
        );
    let mut up = eig.eigenvectors.column(imin).into_owned().normalize();
    // "Up" points from the floor towards the camera (the camera origin).
    if up.dot(&(-centroid)) < 0.0 {
        up = -up;
    }
    let plane_rms_m = (pts
        .iter()
        .map(|p| (p.coords - centroid).dot(&up).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    // Origin: the first view's first corner, dropped onto the plane.
    let o = first_pose.0.translation.vector;
    let origin = o - up * (o - centroid).dot(&up);
    let bx = first_pose.0.rotation * Vector3::x();
    let x = (bx - up * bx.dot(&up)).normalize();
    let y = up.cross(&x);
    let rot = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, up]));
    let floor_to_camera = FloorToCamera(Isometry3::from_parts(
        Translation3::from(origin),
        UnitQuaternion::from_rotation_matrix(&rot),
    ));
    let camera_height_m = (-centroid).dot(&up);
    Ok(FloorPlane {
        floor_to_camera,
        plane_rms_m,
        camera_height_m,
        views: views.iter().map(|v| v.image.clone()).collect(),
    })
}
