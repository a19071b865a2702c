//! Several robots in one video: one [`Tracker`] per tag id over a single decoding pass.
//!
//! Each tracked id keeps its own tracker (its region of interest, prediction and jump
//! rejection), so two robots are never merged and never swapped: a fix is always of the id
//! it is filed under. A tracker that has lost its tag would search the whole frame on every
//! frame; instead one shared full-frame search (decimated) per frame looks for every lost id
//! at once (every third frame for tags long out of view), and only an id it finds is handed
//! to its tracker. With `--tags all` that shared
//! search also discovers ids: every id it sees gets a tracker from that frame on (frames
//! before have no pose for it).

use std::collections::BTreeMap;
use std::sync::mpsc;

use odocal_calib::{CameraModel, FloorToCamera};

use crate::detect::TagDetector;
use crate::source::{decode_into, Batch, Frame, FrameSource};
use crate::track::{
    check_frame_size, unusable_frame, FrameRecord, GapReason, Outcome, RepeatedFixes, TrackOptions,
    TrackResult, Tracker,
};
use crate::TrackError;

/// Frames after its last fix during which a tracker still follows its tag by itself.
const FOLLOW_FRAMES: usize = 5;
/// A tag missing this many frames (or never seen) is searched for on every third frame only:
/// a robot out of view costs a third of the full-frame searches, and one coming into view is
/// found at most two frames late.
const SLOW_SEARCH_AFTER: usize = 15;

/// Which tags to track.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TagSelection {
    /// These ids.
    Ids(Vec<u32>),
    /// Every id of the family that appears.
    All,
}

impl TagSelection {
    /// Parses `all` or a comma-separated list of ids (`0,3,7`).
    pub fn parse(s: &str) -> Result<Self, TrackError> {
        if s.trim() == "all" {
            return Ok(Self::All);
        }
        let mut ids = Vec::new();
        for part in s.split(',') {
            let id: u32 = part.trim().parse().map_err(|_| {
                TrackError::Options(format!(
                    "--tags {s:?}: {part:?} is not a tag id; give ids separated by commas (0,3,7) or all"
                ))
            })?;
            if ids.contains(&id) {
                return Err(TrackError::Options(format!(
                    "--tags {s:?}: id {id} is given twice"
                )));
            }
            ids.push(id);
        }
        Ok(Self::Ids(ids))
    }

    /// Refuses an id that `family` does not hold (see [`crate::check_tag_id`]).
    pub fn check(&self, family: &str) -> Result<(), TrackError> {
        if let Self::Ids(ids) = self {
            for &id in ids {
                crate::check_tag_id(family, id, "--tags")?;
            }
        }
        Ok(())
    }
}

struct IdState {
    tracker: Tracker,
    records: Vec<FrameRecord>,
    last_fix: Option<usize>,
    repeated: RepeatedFixes,
}

/// Tracks every selected tag through a source in one pass; one [`TrackResult`] per id, with a
/// record of every frame of the source (a tag first seen part way in has gaps before; an id
/// with no fix is kept, with its gaps).
/// `on_frame` is called once per frame.
pub fn track_source_multi(
    mut source: Box<dyn FrameSource>,
    camera: &CameraModel,
    floor: &FloorToCamera,
    opts: &TrackOptions,
    selection: &TagSelection,
    on_frame: &mut dyn FnMut(&Frame),
) -> Result<BTreeMap<u32, TrackResult>, TrackError> {
    let info = source.info().clone();
    check_frame_size(&info, camera)?;
    let new_state = |id: u32| -> Result<IdState, TrackError> {
        Ok(IdState {
            tracker: Tracker::new(
                *camera,
                *floor,
                TrackOptions {
                    tag_id: id,
                    ..opts.clone()
                },
            )?,
            records: Vec::new(),
            last_fix: None,
            repeated: RepeatedFixes::default(),
        })
    };
    let mut states: BTreeMap<u32, IdState> = BTreeMap::new();
    if let TagSelection::Ids(ids) = selection {
        for &id in ids {
            states.insert(id, new_state(id)?);
        }
    }
    let mut search = TagDetector::new(
        &opts.family,
        opts.max_hamming.min(3) as usize,
        opts.search_decimate.max(1.0),
    )?;
    let mut seen: BTreeMap<u32, usize> = BTreeMap::new();
    // Every frame so far as a gap, for a tag first seen part way in: its timeline is the
    // video's, not one that starts where it came into view (which read as a file cut short).
    let mut before_seen: Vec<FrameRecord> = Vec::new();
    let (tx, rx) = mpsc::sync_channel::<Batch>(3);
    let final_info = std::thread::scope(|scope| -> Result<_, TrackError> {
        let decoder = scope.spawn(move || decode_into(source.as_mut(), tx));
        let mut previous: Option<Frame> = None;
        for batch in rx {
            let mut batch = batch?;
            if batch.is_empty() {
                break;
            }
            for k in 0..batch.len() {
                let frame = &batch[k];
                let before = if k > 0 {
                    batch.get(k - 1)
                } else {
                    previous.as_ref()
                };
                let unusable = unusable_frame(frame, before, camera, &info.path)?;
                let following = |s: &IdState| {
                    s.last_fix
                        .is_some_and(|i| frame.index.saturating_sub(i) <= FOLLOW_FRAMES)
                };
                let urgent = |s: &IdState| {
                    !following(s)
                        && s.last_fix
                            .is_some_and(|i| frame.index.saturating_sub(i) <= SLOW_SEARCH_AFTER)
                };
                let lost =
                    *selection == TagSelection::All || states.values().any(|s| !following(s));
                let need_search = unusable.is_none()
                    && lost
                    && (frame.index % 3 == 0 || states.values().any(urgent));
                let found: Vec<u32> = if need_search {
                    let mut ids: Vec<u32> = search
                        .detect(&frame.image, None)?
                        .iter()
                        .map(|d| d.id)
                        .collect();
                    ids.sort_unstable();
                    ids.dedup();
                    ids
                } else {
                    vec![]
                };
                for id in &found {
                    *seen.entry(*id).or_insert(0) += 1;
                }
                if *selection == TagSelection::All {
                    for id in &found {
                        if !states.contains_key(id) {
                            let mut state = new_state(*id)?;
                            state.records = before_seen.clone();
                            states.insert(*id, state);
                        }
                    }
                }
                if *selection == TagSelection::All {
                    before_seen.push(gap(frame, unusable.unwrap_or(GapReason::NotDetected)));
                }
                for (id, s) in states.iter_mut() {
                    let mut rec = match unusable {
                        Some(reason) => gap(frame, reason),
                        None if following(s) || found.contains(id) => s.tracker.process(frame)?,
                        None => gap(frame, GapReason::NotDetected),
                    };
                    s.repeated.screen(&mut rec);
                    if matches!(rec.outcome, Outcome::Fix(_)) {
                        s.last_fix = Some(frame.index);
                    }
                    s.records.push(rec);
                }
                on_frame(frame);
            }
            previous = batch.pop();
        }
        decoder
            .join()
            .map_err(|_| TrackError::bad_input(&info.path, "the frame decoder stopped on a panic"))
    })?;
    for s in states.values() {
        for (id, n) in s.tracker.seen_ids() {
            let e = seen.entry(*id).or_insert(0);
            *e = (*e).max(*n);
        }
    }
    Ok(states
        .into_iter()
        .map(|(id, mut s)| {
            // Each tag's repeated images go to their slots as a single tag's do: one robot
            // may stand still (its fixes repeat) while another drives on.
            crate::repeats::place_repeated_images(&mut s.records);
            (
                id,
                TrackResult {
                    tag_to_robot: opts.tag_to_robot,
                    records: s.records,
                    lost_in_file: Vec::new(),
                    dropped_by_motion: Vec::new(),
                    seen_ids: seen.clone(),
                    frame_size: (info.width, info.height),
                    source: final_info.clone(),
                },
            )
        })
        .collect())
}

fn gap(frame: &Frame, reason: GapReason) -> FrameRecord {
    FrameRecord {
        index: frame.index,
        t_s: frame.t_s,
        outcome: Outcome::Gap(reason),
        rejected: None,
        other_tag: None,
    }
}
