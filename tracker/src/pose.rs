//! From tag corners to the marker's floor pose.
//!
//! The marker is horizontal at a known height, so the estimate is planar: each
//! corner's undistorted ray is intersected with the plane z = marker height and
//! the tag's square is fitted to the four floor points by a least-squares 2-D
//! rigid fit. OpenCV's 6-DoF solvePnP (IPPE_SQUARE) is computed only as a
//! cross-check of the planar assumption.

use nalgebra::{Isometry3, Matrix3, Point2, Point3};
use odocal_calib::{CameraModel, FloorToCamera};
use odocal_core::{fit_rigid, wrap_angle, Pose2};
use opencv::calib3d;

use crate::TrackError;

/// The tag's corners in its own frame (x right, y up the printed tag), in the
/// detector's corner order, for a tag whose black square is `tag_size_m` wide.
pub fn tag_model(tag_size_m: f64) -> [Point2<f64>; 4] {
    let h = tag_size_m / 2.0;
    [
        Point2::new(-h, -h),
        Point2::new(h, -h),
        Point2::new(h, h),
        Point2::new(-h, h),
    ]
}

/// The planar floor pose of a tag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarPose {
    /// Tag frame → floor frame.
    pub pose: Pose2,
    /// RMS distance between the fitted square and the floor points, metres.
    pub fit_rms_m: f64,
    /// RMS distance between the detected corners and the fitted square
    /// reprojected into the image, pixels.
    pub reprojection_rms_px: f64,
    /// Side of the square the corners span on the marker plane, metres (the RMS distance of
    /// the floor points from their centre times √2): `tag_size_m` for the right tag.
    pub size_m: f64,
}

/// Planar pose of a tag whose corners were detected at `corners_px`.
pub fn planar_pose(
    camera: &CameraModel,
    floor: &FloorToCamera,
    corners_px: &[Point2<f64>; 4],
    tag_size_m: f64,
    marker_height_m: f64,
) -> Option<PlanarPose> {
    let mut on_floor = [Point2::origin(); 4];
    for (q, c) in on_floor.iter_mut().zip(corners_px) {
        *q = camera.pixel_to_floor(floor, c, marker_height_m)?;
    }
    let model = tag_model(tag_size_m);
    let fit = fit_rigid(&model, &on_floor).ok()?;
    let mut sq = 0.0;
    for (m, c) in model.iter().zip(corners_px) {
        let p = camera.floor_to_pixel(floor, &fit.pose.transform_point(m), marker_height_m)?;
        sq += (p - c).norm_squared();
    }
    let centre = on_floor
        .iter()
        .fold(nalgebra::Vector2::zeros(), |s, p| s + p.coords)
        / 4.0;
    let spread = on_floor
        .iter()
        .map(|p| (p.coords - centre).norm_squared())
        .sum::<f64>()
        / 4.0;
    Some(PlanarPose {
        pose: Pose2::new(fit.pose.x_m, fit.pose.y_m, wrap_angle(fit.pose.theta_rad)),
        fit_rms_m: fit.rms,
        reprojection_rms_px: (sq / 4.0).sqrt(),
        size_m: (2.0 * spread).sqrt(),
    })
}

/// The 6-DoF cross-check of a planar pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnpCheck {
    /// Tag centre height above the floor by solvePnP, metres.
    pub height_m: f64,
    /// Tilt of the tag's normal from the floor normal, radians.
    pub tilt_rad: f64,
    /// Floor position of the PnP tag centre minus the planar one, metres (horizontal distance).
    pub position_diff_m: f64,
    /// PnP heading minus planar heading, radians (wrapped).
    pub heading_diff_rad: f64,
}

/// The tag's pose in the floor frame by solvePnP (IPPE_SQUARE) on its corners alone: its depth
/// comes from `tag_size_m`, not from the marker's height.
pub(crate) fn pnp_tag_to_floor(
    camera: &CameraModel,
    floor: &FloorToCamera,
    corners_px: &[Point2<f64>; 4],
    tag_size_m: f64,
) -> Result<Isometry3<f64>, TrackError> {
    // IPPE_SQUARE wants (-s,+s), (+s,+s), (+s,-s), (-s,-s): detector corners 3, 2, 1, 0.
    let h = tag_size_m / 2.0;
    let object = [
        Point3::new(-h, h, 0.0),
        Point3::new(h, h, 0.0),
        Point3::new(h, -h, 0.0),
        Point3::new(-h, -h, 0.0),
    ];
    let image = [3, 2, 1, 0].map(|i| corners_px[i]);
    let tag_to_camera =
        odocal_calib::solve_pnp(camera, &object, &image, calib3d::SOLVEPNP_IPPE_SQUARE)?
            .ok_or_else(|| TrackError::Options("solvePnP failed".into()))?;
    Ok(floor.0.inverse() * tag_to_camera)
}

/// solvePnP (IPPE_SQUARE) on the same corners, compared with `planar`.
pub fn pnp_cross_check(
    camera: &CameraModel,
    floor: &FloorToCamera,
    corners_px: &[Point2<f64>; 4],
    tag_size_m: f64,
    planar: &PlanarPose,
) -> Result<PnpCheck, TrackError> {
    let tag_to_floor = pnp_tag_to_floor(camera, floor, corners_px, tag_size_m)?;
    let centre = Point3::from(tag_to_floor.translation.vector);
    let r_tf: Matrix3<f64> = *tag_to_floor.rotation.to_rotation_matrix().matrix();
    let x_axis = r_tf.column(0);
    let normal = r_tf.column(2);
    let heading = x_axis.y.atan2(x_axis.x);
    Ok(PnpCheck {
        height_m: centre.z,
        tilt_rad: normal.z.abs().clamp(-1.0, 1.0).acos(),
        position_diff_m: (Point2::new(centre.x, centre.y) - planar.pose.position()).norm(),
        heading_diff_rad: wrap_angle(heading - planar.pose.theta_rad),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    use odocal_calib::Distortion;

    fn setup() -> (CameraModel, FloorToCamera) {
        let mut cam = CameraModel::from_hfov(1280, 720, 70.0);
        cam.distortion = Distortion::pinhole5(-0.1, 0.04, 3e-4, -2e-4, 0.0);
        let rot = UnitQuaternion::from_euler_angles(0.02, -0.015, 0.3)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let c = Vector3::new(0.1, -0.2, 2.2);
        let floor = FloorToCamera(Isometry3::from_parts(Translation3::from(-(rot * c)), rot));
        (cam, floor)
    }

    fn corners(cam: &CameraModel, floor: &FloorToCamera, pose: &Pose2, h: f64) -> [Point2<f64>; 4] {
        tag_model(0.08).map(|m| {
            cam.floor_to_pixel(floor, &pose.transform_point(&m), h)
                .unwrap()
        })
    }

    #[test]
    fn exact_corners_give_the_exact_pose() {
        let (cam, floor) = setup();
        for pose in [Pose2::new(0.3, 0.1, 0.7), Pose2::new(-1.1, 0.6, -2.9)] {
            let c = corners(&cam, &floor, &pose, 0.08);
            let p = planar_pose(&cam, &floor, &c, 0.08, 0.08).unwrap();
            assert!((p.pose.position() - pose.position()).norm() < 1e-9);
            assert!(wrap_angle(p.pose.theta_rad - pose.theta_rad).abs() < 1e-9);
            assert!(p.reprojection_rms_px < 1e-6 && p.fit_rms_m < 1e-9);
            assert!((p.size_m - 0.08).abs() < 1e-9, "{p:?}");
            let chk = pnp_cross_check(&cam, &floor, &c, 0.08, &p).unwrap();
            assert!((chk.height_m - 0.08).abs() < 1e-4, "{chk:?}");
            assert!(
                chk.position_diff_m < 1e-4
                    && chk.heading_diff_rad.abs() < 1e-4
                    && chk.tilt_rad < 1e-3,
                "{chk:?}"
            );
        }
    }

    #[test]
    fn a_tilted_plate_given_its_tilt_gives_the_level_plates_pose() {
        // A plate turned rigidly about its centre (at the marker height) so that it falls
        // 2° toward its x axis and 1° toward its y axis: the corners' places come from the
        // rotation, not from the small-angle heights `flatten` takes.
        let (cam, floor) = setup();
        let (fall_x, fall_y) = (2f64.to_radians(), 1f64.to_radians());
        let plate = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), fall_x)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -fall_y);
        let h = 0.08;
        for pose in [Pose2::new(0.9, 0.5, 0.7), Pose2::new(-1.1, 0.6, -2.9)] {
            let mut c = tag_model(0.08).map(|m| {
                let on_plate = plate * Vector3::new(m.x, m.y, 0.0);
                let q = pose.transform_point(&Point2::new(on_plate.x, on_plate.y));
                cam.floor_to_pixel(&floor, &q, h + on_plate.z).unwrap()
            });
            let as_seen = c;
            let level = planar_pose(&cam, &floor, &c, 0.08, h).unwrap();
            let turned_rad = wrap_angle(level.pose.theta_rad - pose.theta_rad);
            assert!(turned_rad.abs() > 2e-3, "{level:?}");
            let opts = crate::TrackOptions {
                tag_tilt_rad: nalgebra::Vector2::new(fall_x, fall_y),
                ..Default::default()
            };
            crate::track::flatten(&cam, &floor, &opts, &mut c);
            let p = planar_pose(&cam, &floor, &c, 0.08, h).unwrap();
            assert!((p.pose.position() - pose.position()).norm() < 1e-6, "{p:?}");
            // Leaning both ways, the plate's square seen from above is sheared by the
            // product of the two falls (about sin 2° sin 1° / 2 = 0.017° of heading), which
            // the heights alone leave; the level plate's reading was 0.17° off.
            let left_rad = wrap_angle(p.pose.theta_rad - pose.theta_rad).abs();
            assert!(left_rad < 0.5 * fall_x.sin() * fall_y.sin() * 1.1, "{p:?}");
            assert!(left_rad < 0.15 * turned_rad.abs(), "{p:?}");
            // solvePnP then reads the plate as near level: what it still reads is the
            // square's cosine shortening, which a perspective view tells from a tilt only
            // in part.
            let tilt = |c: &[Point2<f64>; 4]| {
                let pnp = pnp_tag_to_floor(&cam, &floor, c, 0.08).unwrap();
                (pnp.rotation * Vector3::z()).z.clamp(-1.0, 1.0).acos()
            };
            assert!(tilt(&c) < 0.1 * tilt(&as_seen), "{} rad", tilt(&c));
        }
    }

    #[test]
    fn a_wrong_marker_height_shows_in_the_fit() {
        // Corners of a tag at 0.12 m read as if at 0.08 m: the square comes out
        // too large, which the rigid fit's residual shows.
        let (cam, floor) = setup();
        let pose = Pose2::new(0.9, -0.4, 0.2);
        let c = corners(&cam, &floor, &pose, 0.12);
        let p = planar_pose(&cam, &floor, &c, 0.08, 0.08).unwrap();
        assert!(p.fit_rms_m > 1e-3, "{p:?}");
        assert!(p.reprojection_rms_px > 0.3, "{p:?}");
    }
}
