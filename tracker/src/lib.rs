//! odocal-tracker (in progress).
