//! odocal-trainer (in progress).
