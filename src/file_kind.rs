//! What a file is from its first bytes, for the messages about a file
//! given in the wrong place: an image given as a recipe, a PNG renamed
//! `.hdr`, an OpenEXR map named `.hdr`.

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
