//! Writing results: files appear whole or not at all (written to a temporary sibling, then
//! renamed), JSON is pretty-printed, and non-finite numbers become `null`.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::error::environment;

/// Writes `bytes` to `path` atomically: a temporary file in the same directory, then a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes).map_err(Into::into))
}

/// Like [`write_atomic`], with a writer callback.
pub fn write_atomic_with(
    path: &Path,
    f: impl FnOnce(&mut dyn Write) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let mut file = AtomicFile::create(path)?;
    f(file.writer()).with_context(|| format!("writing {}", path.display()))?;
    file.commit()
}

/// A file that appears at its path whole or not at all: the bytes go to a temporary file in the
/// same directory, renamed into place by [`AtomicFile::commit`]; dropped without a commit (an
/// error on the way), the temporary file is removed and the path left as it was.
pub struct AtomicFile {
    path: PathBuf,
    w: std::io::BufWriter<tempfile::NamedTempFile>,
}

impl AtomicFile {
    /// Creates the temporary file next to `path` (and `path`'s directory, if it is missing).
    /// An existing path that is not a regular file (a device such as `/dev/null`, a FIFO, a
    /// directory) is refused: renaming over it would replace the device node itself.
    pub fn create(path: &Path) -> anyhow::Result<AtomicFile> {
        if let Ok(meta) = std::fs::metadata(path) {
            if !meta.is_file() {
                return Err(crate::error::bad(format!(
                    "{}: exists and is not a regular file; refusing to replace it (write to a file)",
                    path.display()
                )));
            }
        }
        let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).map_err(|e| environment(format!("creating {}", dir.display()), e))?;
        let tmp = tempfile::NamedTempFile::new_in(dir)
            .map_err(|e| environment(format!("creating a file in {}", dir.display()), e))?;
        // A temporary file is private (0600); the result is an ordinary output file.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            tmp.as_file()
                .set_permissions(std::fs::Permissions::from_mode(0o644))
                .map_err(|e| environment(format!("writing {}", path.display()), e))?;
        }
        Ok(AtomicFile { path: path.to_owned(), w: std::io::BufWriter::new(tmp) })
    }

    /// Where to write the contents (buffered).
    pub fn writer(&mut self) -> &mut impl Write {
        &mut self.w
    }

    /// Flushes the contents and renames the file into place.
    pub fn commit(self) -> anyhow::Result<()> {
        let context = || format!("writing {}", self.path.display());
        let tmp = self.w.into_inner().map_err(|e| environment(context(), e.into_error()))?;
        tmp.persist(&self.path).map_err(|e| environment(context(), e))?;
        Ok(())
    }
}

/// Writes a value as pretty JSON.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> anyhow::Result<()> {
    let s = serde_json::to_string_pretty(value).context("serialising JSON")?;
    write_atomic(path, s.as_bytes())
}

/// A finite number, or `None` (JSON `null`).
pub fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// A Unix time as `YYYY-MM-DDTHH:MM:SSZ` (proleptic Gregorian calendar, days to civil date after
/// H. Hinnant's `civil_from_days`); times before the epoch are shown as the epoch.
pub fn utc_date_time(unix_s: i64) -> String {
    let unix_s = unix_s.max(0);
    let days = unix_s / 86_400;
    let secs = unix_s % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z", secs / 3600, secs / 60 % 60, secs % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_device_or_a_directory_is_never_replaced() {
        let d = tempfile::tempdir().unwrap();
        let e = write_atomic(d.path(), b"x").unwrap_err();
        assert!(e.to_string().contains("is not a regular file"), "{e}");
        assert!(e.downcast_ref::<crate::error::BadInput>().is_some(), "bad input: {e:#}");
        #[cfg(unix)]
        {
            let e = write_atomic(Path::new("/dev/null"), b"x").unwrap_err();
            assert!(e.to_string().starts_with("/dev/null: exists and is not a regular file"), "{e}");
            assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
        }
        let f = d.path().join("out.json");
        write_atomic(&f, b"1").unwrap();
        write_atomic(&f, b"2").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"2");
    }
}
