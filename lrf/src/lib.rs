//! odocal-lrf (in progress).
