//! Image timestamps: a CSV of `file,t` (matched by name) or one `t` per image in natural name
//! order (img2 before img10).

use super::*;

/// Reads image timestamps: CSV with header `file,t` (any order of rows) or `t`
/// (one row per image in natural name order).
pub(super) fn read_timestamps(csv_path: &Path, files: &[PathBuf]) -> Result<Vec<f64>, TrackError> {
    let text = std::fs::read_to_string(csv_path)
        .map_err(|e| TrackError::io(csv_path, format!("cannot read: {e}")))?;
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| TrackError::bad_input(csv_path, e.to_string()))?
        .iter()
        .map(|s| s.to_string())
        .collect();
    let by_name = match header
        .iter()
        .map(|s| s.as_str())
        .collect::<Vec<_>>()
        .as_slice()
    {
        ["file", "t"] => true,
        ["t"] => false,
        _ => {
            return Err(TrackError::bad_input(
                csv_path,
                format!(
                    "line 1: header is \"{}\", expected \"file,t\" or \"t\"",
                    header.join(",")
                ),
            ))
        }
    };
    let mut map = HashMap::new();
    let mut list = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let line = i + 2;
        let rec = rec.map_err(|e| TrackError::bad_input(csv_path, format!("line {line}: {e}")))?;
        let tcol = if by_name { 1 } else { 0 };
        let field = rec.get(tcol).unwrap_or("");
        let t: f64 = field
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite())
            .ok_or_else(|| {
                TrackError::bad_input(
                    csv_path,
                    format!(
                        "line {line}, column {}: {field:?} is not a time in seconds",
                        tcol + 1
                    ),
                )
            })?;
        if by_name {
            map.insert(rec.get(0).unwrap_or("").to_string(), t);
        } else {
            list.push(t);
        }
    }
    let times: Vec<f64> = if by_name {
        files
            .iter()
            .map(|f| {
                let name = f
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                map.get(&name).copied().ok_or_else(|| {
                    // Rows naming the image under a folder are the likeliest miss.
                    let under_folder = map.keys().find(|k| {
                        k.len() > name.len()
                            && k.ends_with(name.as_str())
                            && k[..k.len() - name.len()].ends_with(['/', '\\'])
                    });
                    TrackError::bad_input(
                        csv_path,
                        match under_folder {
                            Some(k) => format!(
                                "names image {name} as \"{k}\": give each image's file name alone, as it is in the folder (\"{name},<t>\")"
                            ),
                            None => format!(
                                "has no timestamp for image {name}: add a row \"{name},<t>\""
                            ),
                        },
                    )
                })
            })
            .collect::<Result<_, _>>()?
    } else {
        if list.len() != files.len() {
            return Err(TrackError::bad_input(
                csv_path,
                format!("has {} timestamps for {} images", list.len(), files.len()),
            ));
        }
        list
    };
    if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
        return Err(TrackError::bad_input(
            csv_path,
            format!(
                "timestamps must increase in image-name order: {} ({}) is not after {} ({})",
                files[k + 1].display(),
                times[k + 1],
                files[k].display(),
                times[k]
            ),
        ));
    }
    // Frames further apart than this are no video of a driving robot: most likely times in
    // milliseconds (a 30 frames/s camera's would be 33 s apart).
    const MAX_MEDIAN_INTERVAL_S: f64 = 2.0;
    let mut dt: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    dt.sort_by(f64::total_cmp);
    if let Some(&median) = dt.get(dt.len() / 2) {
        if median > MAX_MEDIAN_INTERVAL_S {
            // The smallest unit that puts the frames a camera's interval apart.
            let unit = [
                ("milliseconds", 1e3),
                ("microseconds", 1e6),
                ("nanoseconds", 1e9),
            ]
            .into_iter()
            .find(|(_, per_s)| median / per_s <= MAX_MEDIAN_INTERVAL_S)
            .map_or("milliseconds", |(u, _)| u);
            return Err(TrackError::bad_input(
                csv_path,
                format!(
                    "images are a median {median:.3} s apart ({:.3} frames/s): are the timestamps in {unit}? they must be in seconds",
                    1.0 / median
                ),
            ));
        }
    }
    Ok(times)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files(n: usize) -> Vec<PathBuf> {
        (0..n)
            .map(|i| PathBuf::from(format!("/x/frame_{i:02}.png")))
            .collect()
    }

    fn ts(text: &str, n: usize) -> Result<Vec<f64>, TrackError> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ts.csv");
        std::fs::write(&p, text).unwrap();
        read_timestamps(&p, &files(n))
    }

    #[test]
    fn timestamps_by_name_or_by_order() {
        let t = ts("file,t\nframe_01.png,0.5\nframe_00.png,0.25\n", 2).unwrap();
        assert_eq!(t, vec![0.25, 0.5]);
        assert_eq!(ts("t\n1\n2\n3\n", 3).unwrap(), vec![1.0, 2.0, 3.0]);
    }

    #[test]
    fn bad_timestamp_files_say_where() {
        let e = ts("time\n1\n", 1).unwrap_err().to_string();
        assert!(
            e.contains("line 1") && e.contains("expected \"file,t\""),
            "{e}"
        );
        let e = ts("file,t\nframe_00.png,abc\n", 1).unwrap_err().to_string();
        assert!(e.contains("line 2, column 2") && e.contains("abc"), "{e}");
        let e = ts("file,t\nframe_00.png,1\n", 2).unwrap_err().to_string();
        assert!(e.contains("no timestamp for image frame_01.png"), "{e}");
        // Rows naming the images under their folder.
        let e = ts("file,t\nframes/frame_00.png,0\nframes/frame_01.png,1\n", 2)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("names image frame_00.png as \"frames/frame_00.png\": give each image's file name alone"),
            "{e}"
        );
        let e = ts("t\n1\n1\n", 2).unwrap_err().to_string();
        assert!(e.contains("must increase"), "{e}");
        let e = ts("t\n1\n", 2).unwrap_err().to_string();
        assert!(e.contains("1 timestamps for 2 images"), "{e}");
        let e = ts("t\n0\n33.3\n66.7\n", 3).unwrap_err().to_string();
        assert!(
            e.contains("a median 33.400 s apart") && e.contains("in milliseconds?"),
            "{e}"
        );
        // Microseconds were asked about as milliseconds.
        let e = ts("t\n0\n33333\n66667\n", 3).unwrap_err().to_string();
        assert!(e.contains("in microseconds?"), "{e}");
    }
}
