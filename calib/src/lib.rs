//! odocal-calib (in progress).
