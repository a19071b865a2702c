//! What a file given in the wrong place is, from its first bytes, so that an error can say
//! "is a video" or "is a CSV text file" instead of only what it is not.

use std::io::Read;
use std::path::Path;

/// What the file at `path` looks like ("an AVI video", "a CSV text file", ...), or `None`
/// when it cannot be read or is none of the kinds odocal users pass around.
pub fn file_kind(path: &Path) -> Option<&'static str> {
    let mut head = [0u8; 64];
    let n = std::fs::File::open(path).ok()?.read(&mut head).ok()?;
    let head = &head[..n];
    let kind = if head.starts_with(b"RIFF") && head.get(8..11) == Some(b"AVI") {
        "an AVI video"
    } else if head.get(4..8) == Some(b"ftyp") {
        "an MP4 or MOV video"
    } else if head.starts_with(&[0x1a, 0x45, 0xdf, 0xa3]) {
        "a Matroska or WebM video"
    } else if head.starts_with(b"\x89PNG") {
        "a PNG image"
    } else if head.starts_with(&[0xff, 0xd8, 0xff]) {
        "a JPEG image"
    } else if std::str::from_utf8(head).is_ok_and(|t| t.trim_start().starts_with('{')) {
        "a JSON text file"
    } else if std::str::from_utf8(head)
        .is_ok_and(|t| t.lines().next().is_some_and(|l| l.contains(',')))
    {
        "a CSV text file"
    } else {
        return None;
    };
    Some(kind)
}

/// Whether `kind` (from [`file_kind`]) is a video.
pub fn is_video(kind: &str) -> bool {
    kind.ends_with("video")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_from_first_bytes() {
        let dir = tempfile::tempdir().expect("tempdir");
        let at = |name: &str, bytes: &[u8]| {
            let p = dir.path().join(name);
            std::fs::write(&p, bytes).expect("write");
            file_kind(&p)
        };
        assert_eq!(at("a", b"RIFF\x10\0\0\0AVI LIST"), Some("an AVI video"));
        assert_eq!(
            at("b", b"\0\0\0\x20ftypisom\0\0"),
            Some("an MP4 or MOV video")
        );
        assert_eq!(
            at("c", b"t,x,y,theta,quality\n0,1,2,3,1\n"),
            Some("a CSV text file")
        );
        assert_eq!(
            at("d", b"  {\"format\": \"odocal.camera/1\"}"),
            Some("a JSON text file")
        );
        assert_eq!(at("e", b"\x89PNG\r\n\x1a\n"), Some("a PNG image"));
        assert_eq!(at("f", b"\0\x01\x02"), None);
        assert!(is_video("an AVI video") && !is_video("a PNG image"));
    }
}
