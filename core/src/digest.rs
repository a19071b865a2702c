//! Which file a result was made from: the SHA-256 of its bytes, recorded by the outputs
//! that are read beside it later (a model beside its dataset, an arena tracking beside its
//! arena), so a file of another run is refused rather than drawn.

use sha2::{Digest, Sha256};

/// Hex SHA-256 of a file's bytes (what `sha256sum` prints).
pub fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}
