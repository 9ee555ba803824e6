//! Output files written atomically: the bytes go to a temporary file beside the target (same
//! directory, so the same file system), which is flushed to disk and then renamed over the
//! target. A reader sees the old file or the new one, never a part; a write that fails (disk
//! full, killed process) leaves the old file as it was. Images, tables, plots, ray dumps and
//! exported scenes all go through `write`.
use crate::error::{err, Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The temporary file `write` uses for `path`: `.NAME.PID.tmp` in the same directory.
pub fn temporary_path(path: &Path) -> Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| err!(InvalidInput: "{}: not a file name", path.display()))?;
    Ok(path.with_file_name(format!(".{}.{}.tmp", name.to_string_lossy(), std::process::id())))
}

/// Replaces the file at `path` with `bytes` atomically (see the module notes).
pub fn write(path: &Path, bytes: impl AsRef<[u8]>) -> Result<()> {
    let tmp = temporary_path(path)?;
    let written = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes.as_ref())?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    written.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[test]
    fn writes_replace_whole_files_and_leave_no_temporaries() {
        let dir = std::env::temp_dir().join(format!("kdray-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("table.csv");
        write(&path, "a,b\n1,2\n").unwrap();
        write(&path, "a,b\n3,4\n").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a,b\n3,4\n");
        assert_eq!(listing(&dir), ["table.csv"]);
        // A write that cannot complete (the target is a directory) fails with the path named,
        // leaves the target as it was and removes its temporary file.
        let busy = dir.join("busy");
        std::fs::create_dir_all(busy.join("inside")).unwrap();
        let e = write(&busy, "x").unwrap_err();
        assert!(matches!(e.kind(), Error::Io { .. }), "{e}");
        assert!(e.to_string().contains("busy"), "{e}");
        assert!(busy.join("inside").is_dir());
        assert_eq!(listing(&dir), ["busy", "table.csv"]);
        // No directory: an error, nothing written.
        assert!(write(&dir.join("missing").join("x.png"), "x").is_err());
        assert!(write(Path::new("/"), "x").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
