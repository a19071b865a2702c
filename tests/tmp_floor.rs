use nalgebra::Point2;
use odocal_calib::CameraFile;
use odocal_synth::board::CalibTruth;
use std::path::Path;

#[test]
fn tmp_floor() {
    let dirs: Vec<String> = std::env::var("DIRS").unwrap().split(',').map(String::from).collect();
    let rings = [20.0, 30.0, 45.0, 60.0, 75.0, 80.0];
    let mut pooled = vec![(0.0f64, 0usize); rings.len()];
    for d in &dirs {
        let cam = CameraFile::load(&Path::new(d).join("camera.json")).unwrap();
        let truth = CalibTruth::read(&Path::new(d).join("truth.json")).unwrap();
        let ef = &cam.floor.as_ref().unwrap().floor_to_camera;
        let map = cam.floor_uncertainty.as_ref().unwrap();
        let tf = &truth.floor_to_camera;
        let nadir = tf.0.inverse().translation.vector;
        let mut stats = vec![(0.0f64, 0.0f64, 0.0f64, 0usize); rings.len()];
        let w = truth.camera.width as f64; let h = truth.camera.height as f64;
        let mut y = 4.0;
        while y < h {
            let mut x = 4.0;
            while x < w {
                let pix = Point2::new(x, y);
                if let (Some(p), Some(e), Some(s)) = (truth.camera.pixel_to_floor(tf, &pix, 0.0), cam.camera.pixel_to_floor(ef, &pix, 0.0), map.at(&pix)) {
                    let err = (e - p).norm() * 1e3;
                    let off = (p - Point2::new(nadir.x, nadir.y)).norm();
                    let ang = off.atan2(nadir.z).to_degrees();
                    if let Some(i) = rings.iter().position(|r| ang < *r) {
                        let st = &mut stats[i];
                        st.0 = st.0.max(err); st.1 = st.1.max(s); st.2 += (err / s).powi(2); st.3 += 1;
                        pooled[i].0 += (err / s).powi(2); pooled[i].1 += 1;
                    }
                }
                x += 16.0;
            }
            y += 16.0;
        }
        // error vector at the pixel under the camera and at the floor origin
        let under = Point2::new(nadir.x, nadir.y);
        let pix_n = truth.camera.floor_to_pixel(tf, &under, 0.0).unwrap();
        let en = cam.camera.pixel_to_floor(ef, &pix_n, 0.0).unwrap() - under;
        let pix_o = truth.camera.floor_to_pixel(tf, &Point2::origin(), 0.0).unwrap();
        let eo = cam.camera.pixel_to_floor(ef, &pix_o, 0.0).unwrap() - Point2::origin();
        println!("  nadir err ({:.3}, {:.3}) mm σ {:.3}; origin err ({:.3}, {:.3}) mm σ {:.3}; height est {:.5} true {:.5}", en.x*1e3, en.y*1e3, map.at(&pix_n).unwrap_or(f64::NAN), eo.x*1e3, eo.y*1e3, map.at(&pix_o).unwrap_or(f64::NAN), cam.floor.as_ref().unwrap().camera_height_m, nadir.z);
        {
            let b = truth.scene.board;
            let pts = odocal_calib::board_points(&b);
            for (k, fv) in truth.floor_views.iter().enumerate().take(map.floor_boards_px.len()) {
                let det = &map.floor_boards_px[k];
                let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
                let mut rms = 0.0;
                for q in &pts {
                    let t = truth.camera.project(&(fv.board_to_camera.0 * q)).unwrap();
                    let best = det.iter().map(|d| Point2::new(d[0], d[1])).min_by(|a, b| (a - t).norm().total_cmp(&(b - t).norm())).unwrap();
                    let dd = best - t;
                    sx += dd.x; sy += dd.y; n += 1.0; rms += dd.norm_squared();
                }
                println!("    floor board {k}: mean corner offset ({:.4}, {:.4}) px, rms {:.4} px", sx / n, sy / n, (rms / n).sqrt());
            }
        }
        let line: Vec<String> = rings.iter().zip(&stats).filter(|(_, s)| s.3 > 0).map(|(r, s)| format!("<{r}°: err {:.2} σ {:.2} z {:.2}", s.0, s.1, (s.2 / s.3 as f64).sqrt())).collect();
        println!("{d}: {}", line.join(" | "));
    }
    let line: Vec<String> = rings.iter().zip(&pooled).filter(|(_, s)| s.1 > 0).map(|(r, s)| format!("<{r}°: z {:.2}", (s.0 / s.1 as f64).sqrt())).collect();
    println!("pooled: {}", line.join(" | "));
}
