//! Writing results to disk without ever leaving a half-written file: data
//! goes to a temporary file beside the target, which is then renamed over it.

pub mod animation;
pub mod exr;
pub(crate) mod exr_zip;
pub mod tonemap;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The temporary files being written now, so that a process stopped
/// midway (Ctrl-C) can remove them: see [`remove_unfinished_outputs`].
static UNFINISHED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Removes the temporary file of every output being written now; their
/// targets stay as they were. For a process about to exit midway (the
/// command line's Ctrl-C handler), so that it leaves no half-written file.
pub fn remove_unfinished_outputs() {
    let unfinished = UNFINISHED.lock().unwrap_or_else(|e| e.into_inner());
    for tmp in unfinished.iter() {
        let _ = std::fs::remove_file(tmp);
    }
}

/// Why an output could not be written, naming the path.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct OutputError {
    /// The output path as given.
    pub path: String,
    /// What went wrong.
    pub message: String,
}

/// The temporary file beside `path` that its bytes are written to before
/// the rename: `.NAME.PID.tmp`. A name too long to take the extra
/// characters within a file system's 255 bytes keeps its first part and a
/// hash of the whole (names that share a long start, such as a
/// turntable's frames, still get temporary files of their own).
fn temporary_sibling(path: &Path) -> PathBuf {
    /// The longest name kept whole: 255 bytes less the dot, the process
    /// number and `.tmp`.
    const WHOLE_UP_TO_BYTES: usize = 230;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let name = if name.len() <= WHOLE_UP_TO_BYTES {
        name
    } else {
        use std::hash::{Hash, Hasher};
        let mut hasher = std::hash::DefaultHasher::new();
        name.hash(&mut hasher);
        let cut = (0..=128)
            .rev()
            .find(|&k| name.is_char_boundary(k))
            .unwrap_or(0);
        format!("{}~{:016x}", &name[..cut], hasher.finish())
    };
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Check that `path` can be written: its directory exists, it is not a
/// directory nor a read-only file, and a file can be made beside it (its temporary file is
/// made and removed). Called before long work so that errors come first.
pub fn check_writable(path: &Path) -> Result<(), OutputError> {
    let err = |message: String| OutputError {
        path: path.display().to_string(),
        message,
    };
    if path.is_dir() {
        return Err(err("is a directory, expected a file name".into()));
    }
    // Renaming over a file needs only its folder's permission: a file
    // made read-only, to keep it, would be replaced without a word.
    if std::fs::metadata(path).is_ok_and(|meta| meta.permissions().readonly()) {
        return Err(err(
            "is read-only, and is kept: make it writable to replace it, or write another file"
                .into(),
        ));
    }
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
    if let Some(dir) = parent {
        if !dir.is_dir() {
            return Err(err(if dir.exists() {
                format!("{} is a file, not a directory", dir.display())
            } else {
                format!("directory {} does not exist", dir.display())
            }));
        }
    }
    let probe = temporary_sibling(path);
    if !probe.exists() {
        std::fs::File::create(&probe).map_err(|e| err(format!("cannot write: {e}")))?;
        let _ = std::fs::remove_file(&probe);
    }
    Ok(())
}

/// Write `bytes` to `path` atomically (temporary file, then rename).
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_atomically_with(path, |file| {
        file.write_all(bytes).map_err(|e| e.to_string())
    })
}

/// Like [`write_atomically`], for an encoder that streams into the file
/// (so the encoded bytes never sit in memory all at once): `write` fills
/// the temporary sibling, which is synced and renamed over `path` only if
/// `write` succeeds; on any error it is removed and `path` is untouched.
/// `write`'s error message becomes the [`OutputError`]'s.
pub(crate) fn write_atomically_with(
    path: &Path,
    write: impl FnOnce(&mut std::fs::File) -> Result<(), String>,
) -> Result<(), OutputError> {
    check_writable(path)?;
    // Through a symbolic link, the file it points to is replaced and the
    // link kept (renaming over the link would replace the link itself).
    let resolved = path
        .is_symlink()
        .then(|| std::fs::canonicalize(path).ok())
        .flatten();
    let path = resolved.as_deref().unwrap_or(path);
    let tmp = temporary_sibling(path);
    UNFINISHED
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(tmp.clone());
    let result = std::fs::File::create(&tmp)
        .map_err(|e| format!("cannot write: {e}"))
        .and_then(|mut f| {
            write(&mut f)?;
            f.sync_all().map_err(|e| format!("cannot write: {e}"))
        })
        .and_then(|_| std::fs::rename(&tmp, path).map_err(|e| format!("cannot write: {e}")));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    UNFINISHED
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .retain(|pending| *pending != tmp);
    result.map_err(|message| OutputError {
        path: path.display().to_string(),
        message,
    })
}

/// Encode an RGB image as PNG and write it atomically.
pub fn write_png(path: &Path, image: &image::RgbImage) -> Result<(), OutputError> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| OutputError {
            path: path.display().to_string(),
            message: format!("cannot encode PNG: {e}"),
        })?;
    write_atomically(path, &bytes)
}
