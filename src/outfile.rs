//! Output files that are never half-written and never an input.
//!
//! Every command writes its outputs through an [`OutFile`]: the bytes go to a
//! temporary file beside the destination (`.NAME.tmp-PID`), which is flushed,
//! synced and renamed over the destination only by [`OutFile::commit`]. A
//! run that fails (or panics, or is killed) leaves the destination as it was
//! and, except after a kill, no temporary file either (removed on drop).
//!
//! [`refuse_inputs_as_outputs`] is called before anything is created: an
//! output path that is one of the inputs (the same file after resolving
//! links, `..` and hard links) is refused with both names.

use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// A file being written under a temporary name; see the module docs.
pub struct OutFile {
    dest: PathBuf,
    tmp: PathBuf,
    w: Option<BufWriter<File>>,
}

impl OutFile {
    /// Start writing `dest` (its directory must exist).
    pub fn create(dest: &Path) -> io::Result<OutFile> {
        let name = dest.file_name().ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
        let mut tmp_name = std::ffi::OsString::from(".");
        tmp_name.push(name);
        tmp_name.push(format!(".tmp-{}", std::process::id()));
        let tmp = dest.with_file_name(tmp_name);
        let f = File::create(&tmp)?;
        Ok(OutFile { dest: dest.to_path_buf(), tmp, w: Some(BufWriter::with_capacity(1 << 20, f)) })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.dest
    }

    /// Flush, sync and rename over the destination.
    pub fn commit(mut self) -> io::Result<()> {
        let w = self.w.take().expect("OutFile writer present until commit");
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        drop(f);
        fs::rename(&self.tmp, &self.dest)?;
        if let Some(dir) = self.dest.parent() {
            let dir = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }
}

impl Write for OutFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.w.as_mut().expect("OutFile writer present until commit").write(buf)
    }
    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.w.as_mut().expect("OutFile writer present until commit").write_all(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.w.as_mut().expect("OutFile writer present until commit").flush()
    }
}

impl Drop for OutFile {
    fn drop(&mut self) {
        if self.w.take().is_some() {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}

/// Write `bytes` to `dest` through an [`OutFile`].
pub fn write_atomic(dest: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut f = OutFile::create(dest)?;
    f.write_all(bytes)?;
    f.commit()
}

/// Device and inode of an existing file (None when it does not exist).
fn identity(p: &Path) -> Option<(u64, u64)> {
    fs::metadata(p).ok().map(|m| (m.dev(), m.ino()))
}

/// Refuse an output that is one of the inputs (same file after resolving
/// links), or two outputs that are the same path.
pub fn refuse_inputs_as_outputs(inputs: &[&Path], outputs: &[&Path]) -> Result<(), String> {
    for o in outputs {
        if let Some(oid) = identity(o) {
            for i in inputs {
                if identity(i) == Some(oid) {
                    return Err(format!(
                        "output {} is the input {} (the same file): refusing to overwrite an input",
                        o.display(),
                        i.display()
                    ));
                }
            }
        }
    }
    for (k, a) in outputs.iter().enumerate() {
        for b in &outputs[k + 1..] {
            let same = match (identity(a), identity(b)) {
                (Some(x), Some(y)) => x == y,
                _ => a == b,
            };
            if same {
                return Err(format!("outputs {} and {} are the same file", a.display(), b.display()));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commit_replaces_and_drop_leaves_the_old_file() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("out.log");
        fs::write(&p, b"old").unwrap();
        {
            let mut f = OutFile::create(&p).unwrap();
            f.write_all(b"half").unwrap();
            // dropped without commit: a failed run
        }
        assert_eq!(fs::read(&p).unwrap(), b"old");
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 1, "temporary file left behind");
        let mut f = OutFile::create(&p).unwrap();
        f.write_all(b"new").unwrap();
        f.commit().unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"new");
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn an_input_is_never_an_output() {
        let d = tempfile::tempdir().unwrap();
        let a = d.path().join("a.log");
        fs::write(&a, b"x").unwrap();
        let link = d.path().join("link.log");
        std::os::unix::fs::symlink(&a, &link).unwrap();
        let hard = d.path().join("hard.log");
        fs::hard_link(&a, &hard).unwrap();
        let dotted = d.path().join(".").join("a.log");
        for o in [&a, &link, &hard, &dotted] {
            let e = refuse_inputs_as_outputs(&[&a], &[o.as_path()]).unwrap_err();
            assert!(e.contains("refusing to overwrite an input"), "{e}");
        }
        let other = d.path().join("b.log");
        refuse_inputs_as_outputs(&[&a], &[&other]).unwrap();
        assert!(refuse_inputs_as_outputs(&[&a], &[&other, &other]).is_err());
    }
}
