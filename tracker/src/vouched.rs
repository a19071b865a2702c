//! Fixes on floor the calibration does not vouch for. `odocal calibrate` maps the floor's
//! uncertainty over the image and vouches for the floor within [`FLOOR_BOUND_MM`] at
//! [`FLOOR_BOUND_SIGMAS`]; a fix seen where that map is worse (near a wide lens's edge, or
//! beyond the floor boards) carries the larger σ in its row, but a user reading only the
//! positions would take it for ground truth as good as the rest. The run says how many such
//! fixes there are and how far out the floor is vouched for.

use nalgebra::Point2;
use odocal_calib::{
    CameraModel, FloorReach, FloorToCamera, FloorUncertaintyMap, FLOOR_BOUND_MM,
    FLOOR_BOUND_SIGMAS, MODEL_SPREAD_SHARE,
};

use crate::detect::quad_centre;
use crate::TrackResult;

/// The fixes of a run that lie outside the floor the calibration vouches for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnvouchedFixes {
    /// Fixes whose tag centre is seen where the floor map's 1σ, times [`FLOOR_BOUND_SIGMAS`],
    /// exceeds [`FLOOR_BOUND_MM`], or where the map sees no floor at all.
    pub outside: usize,
    /// Of those, fixes where the σ is within the bound but lens models that fit the
    /// calibration's views alike map the floor too far apart.
    pub by_models: usize,
    /// All fixes of the run.
    pub fixes: usize,
    /// The largest floor-map 1σ under those fixes, millimetres (None when every one of them
    /// lies where the map sees no floor).
    pub worst_sigma_mm: Option<f64>,
    /// The disc around the point under the camera the calibration vouches for.
    pub reach: Option<FloorReach>,
}

impl UnvouchedFixes {
    /// Counts the fixes whose tag centres (`centres_px`, pixels) lie outside the floor `map`
    /// vouches for; `camera` and `floor` are the calibration's own. None when every one lies
    /// within it.
    pub fn count(
        centres_px: impl IntoIterator<Item = Point2<f64>>,
        map: &FloorUncertaintyMap,
        camera: &CameraModel,
        floor: &FloorToCamera,
    ) -> Option<Self> {
        let bound_mm = FLOOR_BOUND_MM / FLOOR_BOUND_SIGMAS;
        let (mut outside, mut fixes, mut by_models) = (0usize, 0usize, 0usize);
        let mut worst_sigma_mm: Option<f64> = None;
        for c in centres_px {
            fixes += 1;
            match map.at(&c) {
                Some(_) if map.models_part_at(&c) => {
                    outside += 1;
                    by_models += 1;
                }
                Some(s) if s <= bound_mm => {}
                Some(s) => {
                    outside += 1;
                    worst_sigma_mm = Some(worst_sigma_mm.map_or(s, |w| w.max(s)));
                }
                None => outside += 1,
            }
        }
        (outside > 0).then(|| Self {
            outside,
            by_models,
            fixes,
            worst_sigma_mm,
            reach: map.vouched_reach(camera, floor),
        })
    }

    /// [`Self::count`] over the fixes of `result`.
    pub fn of(
        result: &TrackResult,
        map: &FloorUncertaintyMap,
        camera: &CameraModel,
        floor: &FloorToCamera,
    ) -> Option<Self> {
        let centres = result.fixes().map(|(_, f)| quad_centre(&f.corners_px));
        Self::count(centres, map, camera, floor)
    }

    /// One line for the user: how many fixes, how uncertain the floor is under them, how far
    /// out it is vouched for, and what to do.
    pub fn warning(&self) -> String {
        let share = 100.0 * self.outside as f64 / self.fixes.max(1) as f64;
        let sigma = match self.worst_sigma_mm {
            Some(s) => format!(
                "the calibration alone puts their 1σ up to {s:.1} mm (in each row's sigma_x, sigma_y)"
            ),
            None => "the calibration's floor map does not reach them".to_string(),
        };
        let sigma = if self.by_models > 0 {
            format!(
                "{sigma}; under {} of them the lens models that fit the calibration's views equally well map the floor more than {} mm apart",
                self.by_models,
                MODEL_SPREAD_SHARE * FLOOR_BOUND_MM
            )
        } else {
            sigma
        };
        let reach = match &self.reach {
            Some(r) => format!(
                "it vouches for {:.2} m around the point under the camera ({:.0}° off the nadir)",
                r.radius_m, r.off_nadir_deg
            ),
            None => "it vouches for no floor at all".to_string(),
        };
        format!(
            "{} of {} fixes ({share:.0} %) lie outside the floor the calibration maps within {FLOOR_BOUND_MM} mm at {FLOOR_BOUND_SIGMAS}σ: {sigma}; {reach}; calibrate again with hand-held views reaching the image's edges and floor views where the robot drives, or keep the robot within that floor",
            self.outside, self.fixes
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    use odocal_calib::{Distortion, Intrinsics};

    fn camera() -> (CameraModel, FloorToCamera) {
        let camera = CameraModel {
            width: 40,
            height: 40,
            intrinsics: Intrinsics {
                fx: 30.0,
                fy: 30.0,
                cx: 20.0,
                cy: 20.0,
            },
            distortion: Distortion::default(),
        };
        // Looking straight down from 2 m: floor z up, camera z down.
        let floor = FloorToCamera(Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 2.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
        ));
        (camera, floor)
    }

    /// A 2x2-cell map: σ 0.5 mm in the left column, 1 mm at the top right, no floor at the
    /// bottom right.
    fn map() -> FloorUncertaintyMap {
        FloorUncertaintyMap {
            cell_px: 20,
            cols: 2,
            rows: 2,
            sigma_mm: vec![Some(0.5), Some(1.0), Some(0.5), None],
            floor_boards_px: vec![],
            model_spread_mm: vec![],
            covariance_mm2: vec![],
            floor_covariance: None,
        }
    }

    #[test]
    fn fixes_beyond_the_bound_or_the_map_are_counted() {
        let (camera, floor) = camera();
        let at = |x: f64, y: f64| Point2::new(x, y);
        let inside = [at(5.0, 5.0), at(5.0, 30.0)];
        assert_eq!(UnvouchedFixes::count(inside, &map(), &camera, &floor), None);
        let u = UnvouchedFixes::count(
            [at(5.0, 5.0), at(30.0, 5.0), at(30.0, 30.0), at(-1.0, 3.0)],
            &map(),
            &camera,
            &floor,
        )
        .expect("three outside");
        assert_eq!((u.outside, u.fixes), (3, 4));
        assert_eq!(u.worst_sigma_mm, Some(1.0));
        let w = u.warning();
        assert!(w.starts_with("3 of 4 fixes (75 %)"), "{w}");
        assert!(w.contains("1σ up to 1.0 mm"), "{w}");
        // The left column's cells are vouched for; the nearest cell over the bound is the top
        // right one, whose centre (30, 10) px is 10 px from the principal point along both
        // axes: a third of the 2 m height each way on the floor.
        let r = u.reach.expect("a reach");
        assert!(!r.whole);
        assert!((r.radius_m - 2.0 * 2f64.sqrt() / 3.0).abs() < 1e-9, "{r:?}");
        // Lens models that part by 1.5 mm at the bottom left (σ 0.5 mm there): not vouched
        // for.
        let mut parted = map();
        parted.model_spread_mm = vec![Some(0.2), Some(0.3), Some(1.5), None];
        let u = UnvouchedFixes::count(inside, &parted, &camera, &floor).expect("one outside");
        assert_eq!((u.outside, u.by_models, u.fixes), (1, 1, 2));
        assert!(
            u.warning()
                .contains("under 1 of them the lens models that fit the calibration's views equally well map the floor more than 1 mm apart"),
            "{}",
            u.warning()
        );
    }
}
