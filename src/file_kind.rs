//! What a file is from its first bytes, for the messages about a file
//! given in the wrong place: an image given as a recipe, a PNG renamed
//! `.hdr`, an OpenEXR map named `.hdr`; and what a path is when it is no
//! regular file (a pipe would keep a reader waiting, a device like
//! `/dev/zero` never ends).

use std::path::Path;

/// A kind of file told by its first bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FileKind {
    Png,
    Jpeg,
    Tiff,
    Gif,
    /// RIFF: WebP among others.
    Riff,
    OpenExr,
    /// Radiance RGBE (`#?RADIANCE`, `#?RGBE`, …).
    RadianceHdr,
    /// UTF-16 text, by its byte-order mark.
    Utf16,
}

/// Each kind's first bytes.
const SIGNATURES: [(&[u8], FileKind); 10] = [
    (b"\x89PNG", FileKind::Png),
    (b"\xff\xd8\xff", FileKind::Jpeg),
    (b"II*\0", FileKind::Tiff),
    (b"MM\0*", FileKind::Tiff),
    (b"GIF8", FileKind::Gif),
    (b"RIFF", FileKind::Riff),
    (b"\x76\x2f\x31\x01", FileKind::OpenExr),
    (b"#?", FileKind::RadianceHdr),
    (b"\xff\xfe", FileKind::Utf16),
    (b"\xfe\xff", FileKind::Utf16),
];

impl FileKind {
    /// The kind a file whose first bytes are `start` is, when one of these.
    pub(crate) fn of(start: &[u8]) -> Option<FileKind> {
        SIGNATURES
            .iter()
            .find(|(signature, _)| start.starts_with(signature))
            .map(|&(_, kind)| kind)
    }

    /// The kind in words, with its article ("a PNG image").
    pub(crate) fn name(self) -> &'static str {
        match self {
            FileKind::Png => "a PNG image",
            FileKind::Jpeg => "a JPEG image",
            FileKind::Tiff => "a TIFF image",
            FileKind::Gif => "a GIF image",
            FileKind::Riff => "a RIFF file (WebP?)",
            FileKind::OpenExr => "an OpenEXR image",
            FileKind::RadianceHdr => "a Radiance HDR image",
            FileKind::Utf16 => "UTF-16 text",
        }
    }
}

/// What `path` is, in words with their article, when it is not a regular
/// file (after symbolic links): "a directory", "a pipe", "a device", "a
/// socket". None for a regular file, and for a path that cannot be looked
/// at (opening it then says why). Asked before a file is opened, since
/// opening a pipe waits for a writer.
pub(crate) fn not_a_regular_file(path: &Path) -> Option<&'static str> {
    let kind = std::fs::metadata(path).ok()?.file_type();
    if kind.is_file() {
        return None;
    }
    if kind.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return Some("a pipe");
        }
        if kind.is_socket() {
            return Some("a socket");
        }
        if kind.is_block_device() || kind.is_char_device() {
            return Some("a device");
        }
    }
    Some("not a regular file")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_and_devices_are_no_regular_files() {
        assert_eq!(not_a_regular_file(Path::new(".")), Some("a directory"));
        assert_eq!(not_a_regular_file(Path::new("Cargo.toml")), None);
        assert_eq!(not_a_regular_file(Path::new("no/such/file")), None);
        #[cfg(unix)]
        assert_eq!(not_a_regular_file(Path::new("/dev/zero")), Some("a device"));
    }
}
