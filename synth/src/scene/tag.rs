//! Tag bitmaps drawn by the renderer, taken from the detector's own C library so the
//! renderer and the tracker cannot disagree about a tag's pattern.

use super::*;

/// The tag36h11 pattern of `id` from the detector's own C library: cells
/// (row-major, true = white), cells per side including the white border, and
/// cells spanned by the black square.
pub fn tag36h11_pattern(id: u32) -> Result<(Vec<bool>, usize, usize), SceneError> {
    // SAFETY: the family is created and destroyed here; apriltag_to_image returns a
    // fresh image we read within its width/height/stride and then destroy.
    unsafe {
        let fam = apriltag_sys::tag36h11_create();
        if fam.is_null() {
            return Err(SceneError::Input("tag36h11_create failed".into()));
        }
        let ncodes = (*fam).ncodes;
        let at_border = (*fam).width_at_border as usize;
        if id >= ncodes {
            apriltag_sys::tag36h11_destroy(fam);
            return Err(SceneError::Input(format!(
                "tag36h11 has ids 0..{}, not {id}",
                ncodes - 1
            )));
        }
        let im = apriltag_sys::apriltag_to_image(fam, id);
        apriltag_sys::tag36h11_destroy(fam);
        if im.is_null() {
            return Err(SceneError::Input("apriltag_to_image failed".into()));
        }
        let (w, h, stride) = (
            (*im).width as usize,
            (*im).height as usize,
            (*im).stride as usize,
        );
        let buf = std::slice::from_raw_parts((*im).buf, stride * h);
        let mut cells = Vec::with_capacity(w * h);
        for r in 0..h {
            for c in 0..w {
                cells.push(buf[r * stride + c] > 127);
            }
        }
        apriltag_sys::image_u8_destroy(im);
        if w != h {
            return Err(SceneError::Input("tag image is not square".into()));
        }
        Ok((cells, w, at_border))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tag_pattern_has_black_ring_and_white_border() {
        let (cells, n, b) = tag36h11_pattern(0).unwrap();
        assert_eq!((n, b), (10, 8));
        for i in 0..n {
            assert!(cells[i] && cells[(n - 1) * n + i] && cells[i * n] && cells[i * n + n - 1]);
            if (1..n - 1).contains(&i) {
                assert!(!cells[n + i] && !cells[i * n + 1]);
            }
        }
        assert!(tag36h11_pattern(100_000).is_err());
    }
}
