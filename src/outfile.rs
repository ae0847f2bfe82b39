//! Output files that are never half-written and never an input.
//!
//! Every command writes its outputs through an [`OutFile`]. A regular file
//! (or a name that does not exist yet) is written to a temporary file beside
//! it (`.NAME.tmp-PID-N`, shortened to fit `NAME_MAX`), which is flushed,
//! synced and renamed over the destination only by [`OutFile::commit`]. A
//! run that fails, panics or is stopped by SIGINT, SIGTERM or SIGHUP leaves
//! the destination as it was and no temporary file (removed on drop, and by
//! a signal handler installed with the first output; only SIGKILL can leave
//! one behind).
//!
//! A symbolic link keeps being a link: the temporary file is made beside the
//! link's target and renamed over the target. What is not a regular file is
//! never replaced: a character device (`/dev/null`, `/dev/full`), a FIFO or a
//! socket is opened and written directly, and `/dev/stdout`, `/dev/stderr`,
//! `/dev/fd/N` and `/proc/self/fd/N` write to the process's own descriptor
//! (so a shell's `>>` still appends). Their write errors (`/dev/full`'s
//! ENOSPC) are reported at the write or at [`OutFile::commit`]. A directory
//! is refused before anything is created.
//!
//! [`refuse_inputs_as_outputs`] is called before anything is created: an
//! output path that is one of the inputs (the same file after resolving
//! links, `..` and hard links) is refused with both names.

use std::ffi::{CString, OsString};
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::os::unix::ffi::{OsStrExt, OsStringExt};
use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::os::unix::io::{AsRawFd, FromRawFd};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicPtr, AtomicUsize, Ordering};

/// The longest file name the kernel takes (Linux `NAME_MAX`, bytes).
const NAME_MAX: usize = 255;

/// A file being written; see the module docs.
pub struct OutFile {
    dest: PathBuf,
    /// The temporary name (None: written directly, a device, FIFO or fd).
    tmp: Option<Tmp>,
    w: Option<BufWriter<File>>,
}

/// A temporary file and its slot in the signal handler's table.
struct Tmp {
    path: PathBuf,
    /// What it is renamed over: the destination, or its link's target.
    real: PathBuf,
    slot: Option<usize>,
}

/// Where the bytes for `dest` go.
enum Target {
    /// A regular file or a new name: temp and rename over this path.
    Replace(PathBuf),
    /// Written in place: a device, FIFO or socket, opened by this path.
    Device(PathBuf),
    /// The process's own descriptor.
    Fd(i32),
}

/// `/dev/stdout`, `/dev/stderr`, `/dev/fd/N`, `/proc/self/fd/N`: the descriptor.
fn own_fd(p: &Path) -> Option<i32> {
    let s = p.to_str()?;
    match s {
        "/dev/stdout" => return Some(1),
        "/dev/stderr" => return Some(2),
        "/dev/stdin" => return Some(0),
        _ => {}
    }
    let n = s.strip_prefix("/dev/fd/").or_else(|| s.strip_prefix("/proc/self/fd/"))?;
    n.parse().ok().filter(|n| *n >= 0)
}

/// Follow `dest`'s symbolic links (at most 40, as the kernel does) and say
/// how it is written.
fn target(dest: &Path) -> io::Result<Target> {
    let mut p = dest.to_path_buf();
    for _ in 0..40 {
        if let Some(fd) = own_fd(&p) {
            return Ok(Target::Fd(fd));
        }
        let meta = match fs::symlink_metadata(&p) {
            Ok(m) => m,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Target::Replace(p)),
            Err(e) => return Err(e),
        };
        let ft = meta.file_type();
        if ft.is_symlink() {
            let to = fs::read_link(&p)?;
            p = if to.is_absolute() { to } else { p.parent().unwrap_or(Path::new("")).join(to) };
            continue;
        }
        if ft.is_dir() {
            return Err(io::Error::new(io::ErrorKind::InvalidInput, "is a directory, not a file"));
        }
        if ft.is_file() {
            return Ok(Target::Replace(p));
        }
        if ft.is_char_device() || ft.is_fifo() || ft.is_socket() || ft.is_block_device() {
            return Ok(Target::Device(p));
        }
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "is neither a file nor a device"));
    }
    Err(io::Error::new(io::ErrorKind::InvalidInput, "too many levels of symbolic links"))
}

/// `.NAME.tmp-PID-N` beside `dest`, within `NAME_MAX` bytes.
fn tmp_name(dest: &Path) -> io::Result<PathBuf> {
    static SEQ: AtomicUsize = AtomicUsize::new(0);
    let name = dest.file_name().ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
    let suffix = format!(".tmp-{}-{}", std::process::id(), SEQ.fetch_add(1, Ordering::Relaxed));
    let mut bytes = name.as_bytes().to_vec();
    bytes.truncate(NAME_MAX - 1 - suffix.len());
    let mut tmp = OsString::from(".");
    tmp.push(OsString::from_vec(bytes));
    tmp.push(suffix);
    Ok(dest.with_file_name(tmp))
}

impl OutFile {
    /// Start writing `dest` (its directory must exist).
    pub fn create(dest: &Path) -> io::Result<OutFile> {
        let (tmp, f) = match target(dest)? {
            Target::Replace(real) => {
                let path = tmp_name(&real)?;
                // registered before it exists: a signal between the two
                // would otherwise end the process with the file left behind
                let slot = signals::register(&path);
                let f = match OpenOptions::new().write(true).create_new(true).open(&path) {
                    Ok(f) => f,
                    Err(e) => {
                        signals::unregister(slot);
                        return Err(e);
                    }
                };
                (Some(Tmp { path, real, slot }), f)
            }
            Target::Device(p) => (None, OpenOptions::new().write(true).open(p)?),
            Target::Fd(fd) => {
                // SAFETY: dup returns a new descriptor this File then owns.
                let d = unsafe { libc::dup(fd) };
                if d < 0 {
                    return Err(io::Error::last_os_error());
                }
                (None, unsafe { File::from_raw_fd(d) })
            }
        };
        Ok(OutFile { dest: dest.to_path_buf(), tmp, w: Some(BufWriter::with_capacity(1 << 20, f)) })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.dest
    }

    /// Write out what is buffered and ask the kernel to start writing the
    /// file to disk without waiting for it (`sync_file_range`), so that
    /// [`OutFile::commit`]'s sync has less left to wait for; a writer that
    /// produces a large file calls it now and then. Advisory: a device or
    /// pipe that cannot do it is left as it is.
    pub fn start_writeback(&mut self) -> io::Result<()> {
        let w = self.w.as_mut().expect("OutFile writer present until commit");
        w.flush()?;
        // SAFETY: the descriptor is the open file's; the call only schedules writeback.
        let _ = unsafe { libc::sync_file_range(w.get_ref().as_raw_fd(), 0, 0, libc::SYNC_FILE_RANGE_WRITE) };
        Ok(())
    }

    /// Flush, sync and rename over the destination (a device or descriptor:
    /// flush and report its error).
    pub fn commit(mut self) -> io::Result<()> {
        let w = self.w.take().expect("OutFile writer present until commit");
        let Some(tmp) = self.tmp.take() else {
            let f = w.into_inner().map_err(|e| e.into_error())?;
            // a pipe or a terminal cannot be synced; its writes have been made
            let _ = f.sync_all();
            return Ok(());
        };
        let done = (|| {
            let f = w.into_inner().map_err(|e| e.into_error())?;
            f.sync_all()?;
            drop(f);
            fs::rename(&tmp.path, &tmp.real)?;
            if let Some(dir) = tmp.real.parent() {
                let dir = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
                if let Ok(d) = File::open(dir) {
                    let _ = d.sync_all();
                }
            }
            Ok(())
        })();
        if done.is_err() {
            let _ = fs::remove_file(&tmp.path);
        }
        signals::unregister(tmp.slot);
        done
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
        if let Some(tmp) = self.tmp.take() {
            drop(self.w.take());
            let _ = fs::remove_file(&tmp.path);
            signals::unregister(tmp.slot);
        }
    }
}

/// The temporary files to remove on SIGINT, SIGTERM or SIGHUP: a fixed
/// table of C strings the handler reads without locking or allocating
/// (`unlink` is async-signal-safe). A name is leaked when unregistered
/// rather than freed, so the handler never reads freed memory; commands
/// write a handful of outputs.
mod signals {
    use super::*;
    use std::sync::Once;

    const SLOTS: usize = 64;
    static TABLE: [AtomicPtr<libc::c_char>; SLOTS] = [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];

    /// Directories to remove (after the files: a staging directory whose
    /// files are being written).
    static DIRS: [AtomicPtr<libc::c_char>; 8] = [const { AtomicPtr::new(std::ptr::null_mut()) }; 8];

    extern "C" fn on_signal(sig: libc::c_int) {
        for (table, remove) in
            [(&TABLE[..], libc::unlink as unsafe extern "C" fn(*const libc::c_char) -> libc::c_int), (&DIRS[..], libc::rmdir)]
        {
            for s in table {
                let p = s.swap(std::ptr::null_mut(), Ordering::SeqCst);
                if !p.is_null() {
                    // SAFETY: p is a leaked, NUL-terminated CString never freed.
                    unsafe { remove(p) };
                }
            }
        }
        // SAFETY: restore the default action and re-raise, so the exit
        // status says the signal, as it would have without this handler.
        unsafe {
            libc::signal(sig, libc::SIG_DFL);
            libc::raise(sig);
        }
    }

    fn install() {
        static ONCE: Once = Once::new();
        ONCE.call_once(|| {
            for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                // SAFETY: a handler that only unlinks and re-raises.
                unsafe {
                    let mut sa: libc::sigaction = std::mem::zeroed();
                    sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as usize;
                    libc::sigemptyset(&mut sa.sa_mask);
                    let mut old: libc::sigaction = std::mem::zeroed();
                    libc::sigaction(sig, std::ptr::null(), &mut old);
                    // a signal the caller ignores (nohup) stays ignored
                    if old.sa_sigaction != libc::SIG_IGN {
                        libc::sigaction(sig, &sa, std::ptr::null_mut());
                    }
                }
            }
        });
    }

    /// Put `p` in the table (None when the table is full: the file is then
    /// removed on drop only).
    pub(super) fn register(p: &Path) -> Option<usize> {
        register_in(&TABLE, p)
    }

    /// Put the directory `p` in the table of directories.
    pub(super) fn register_dir(p: &Path) -> Option<usize> {
        register_in(&DIRS, p)
    }

    pub(super) fn unregister_dir(slot: Option<usize>) {
        if let Some(k) = slot {
            DIRS[k].store(std::ptr::null_mut(), Ordering::SeqCst);
        }
    }

    fn register_in(table: &[AtomicPtr<libc::c_char>], p: &Path) -> Option<usize> {
        install();
        let c = CString::new(p.as_os_str().as_bytes()).ok()?.into_raw();
        for (k, s) in table.iter().enumerate() {
            if s.compare_exchange(std::ptr::null_mut(), c, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
                return Some(k);
            }
        }
        // SAFETY: c came from into_raw above and was never shared.
        drop(unsafe { CString::from_raw(c) });
        None
    }

    pub(super) fn unregister(slot: Option<usize>) {
        if let Some(k) = slot {
            TABLE[k].store(std::ptr::null_mut(), Ordering::SeqCst);
        }
    }
}

/// A staging directory removed (when empty) by SIGINT, SIGTERM or SIGHUP,
/// after the temporary files being written in it; dropping the guard takes
/// it off the list (the directory's owner removes it otherwise).
pub struct DirGuard(Option<usize>);

/// Remove `dir` on a signal while the guard lives; see [`DirGuard`].
pub fn remove_dir_on_signal(dir: &Path) -> DirGuard {
    DirGuard(signals::register_dir(dir))
}

impl Drop for DirGuard {
    fn drop(&mut self) {
        signals::unregister_dir(self.0);
    }
}

/// Create the output directory `dir` and its parents; a `dir` that exists
/// as something else than a directory (a file, a FIFO) is an error saying
/// so (create_dir_all said `File exists (os error 17)`).
pub fn create_dir(dir: &Path) -> io::Result<()> {
    if let Ok(m) = fs::metadata(dir) {
        if !m.is_dir() {
            return Err(io::Error::new(
                io::ErrorKind::AlreadyExists,
                "is not a directory (a file of that name exists): the output directory must be a directory or a new name",
            ));
        }
        return Ok(());
    }
    fs::create_dir_all(dir)
}

/// Write `bytes` to `dest` through an [`OutFile`].
pub fn write_atomic(dest: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut f = OutFile::create(dest)?;
    f.write_all(bytes)?;
    f.commit()
}

/// Device and inode of an existing regular file (None when it does not
/// exist, or is a device, FIFO or terminal: those are written in place,
/// never replaced, so `--output /dev/null --csv /dev/null` is no conflict).
fn identity(p: &Path) -> Option<(u64, u64)> {
    fs::metadata(p).ok().filter(|m| m.is_file()).map(|m| (m.dev(), m.ino()))
}

/// Whether two paths name the same existing regular file (after links,
/// `..` and hard links).
pub fn same_file(a: &Path, b: &Path) -> bool {
    matches!((identity(a), identity(b)), (Some(x), Some(y)) if x == y)
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
                _ => a == b && !fs::metadata(a).is_ok_and(|m| !m.is_file()),
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

    #[test]
    fn a_link_stays_a_link_and_its_target_is_written() {
        let d = tempfile::tempdir().unwrap();
        let sub = d.path().join("sub");
        fs::create_dir(&sub).unwrap();
        let real = sub.join("real.log");
        fs::write(&real, b"old").unwrap();
        let link = d.path().join("link.log");
        std::os::unix::fs::symlink("sub/real.log", &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link was replaced by a file");
        assert_eq!(fs::read(&real).unwrap(), b"new");
        assert_eq!(fs::read_dir(&sub).unwrap().count(), 1, "temporary file left beside the target");
        // a dangling link makes its target
        let dangling = d.path().join("dangling.log");
        std::os::unix::fs::symlink("sub/new.log", &dangling).unwrap();
        write_atomic(&dangling, b"made").unwrap();
        assert_eq!(fs::read(sub.join("new.log")).unwrap(), b"made");
    }

    #[test]
    fn a_fifo_is_written_in_place_and_stays_a_fifo() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("pipe");
        let c = CString::new(p.as_os_str().as_bytes()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let reader = {
            let p = p.clone();
            std::thread::spawn(move || fs::read(p).unwrap())
        };
        write_atomic(&p, b"through the pipe").unwrap();
        assert_eq!(reader.join().unwrap(), b"through the pipe");
        assert!(fs::symlink_metadata(&p).unwrap().file_type().is_fifo());
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 1);
    }

    /// A device node like `/dev/full` (1, 7) made in `dir` when we may (as
    /// root), so that a broken writer replaces a node of the test's own and
    /// never the host's; otherwise the host's, which a non-root user cannot
    /// replace.
    fn device(dir: &Path, name: &str, minor: u32) -> PathBuf {
        let p = dir.join(name);
        let c = CString::new(p.as_os_str().as_bytes()).unwrap();
        if unsafe { libc::mknod(c.as_ptr(), libc::S_IFCHR | 0o666, libc::makedev(1, minor)) } == 0 {
            p
        } else {
            PathBuf::from(format!("/dev/{name}"))
        }
    }

    #[test]
    fn a_device_is_written_in_place_and_a_full_one_reports_its_error() {
        let d = tempfile::tempdir().unwrap();
        let full = device(d.path(), "full", 7);
        let e = write_atomic(&full, &[0u8; 4096]).unwrap_err();
        assert_eq!(e.raw_os_error(), Some(libc::ENOSPC), "{e}");
        let null = device(d.path(), "null", 3);
        write_atomic(&null, b"gone").unwrap();
        for p in [&full, &null] {
            assert!(fs::symlink_metadata(p).unwrap().file_type().is_char_device(), "{} was replaced", p.display());
        }
        assert!(fs::read_dir(d.path()).unwrap().all(|e| e.unwrap().file_type().unwrap().is_char_device()));
    }

    #[test]
    fn a_directory_is_refused_and_nothing_is_left() {
        let d = tempfile::tempdir().unwrap();
        let sub = d.path().join("sub");
        fs::create_dir(&sub).unwrap();
        let e = OutFile::create(&sub).err().unwrap();
        assert!(e.to_string().contains("is a directory"), "{e}");
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_name_at_the_length_limit_is_written() {
        let d = tempfile::tempdir().unwrap();
        for n in [250, NAME_MAX] {
            let p = d.path().join("x".repeat(n));
            write_atomic(&p, b"long").unwrap();
            assert_eq!(fs::read(&p).unwrap(), b"long");
        }
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 2);
    }
}
