//! Writing a file so that a crash, a `kill -9` or a power loss at any instant leaves
//! either the old complete file or the new complete one, never a mixture: the new bytes
//! go to a temporary file in the same directory (so the rename cannot cross file
//! systems), which is flushed to the disk (fsync), then renamed over the old file (POSIX
//! rename(2) replaces the name atomically), and the directory itself is flushed so the
//! rename survives a power loss (the name lives in the directory, not in the file).
//!
//! A process killed before its rename leaves its temporary file behind; the old file is
//! untouched. [`remove_stale_temporaries`] clears those of processes no longer running.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Marks a temporary file of [`write_atomically`]: `.NAME.tmp.PID.N`.
const TEMP_MARK: &str = ".tmp.";

/// Temporary files of this process get distinct names (several saves may be under way).
static TEMP_SERIAL: AtomicU64 = AtomicU64::new(0);

/// Which step of an atomic write failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Creating the temporary file.
    Create,
    /// Writing the bytes into it.
    Write,
    /// Flushing it to the disk (fsync).
    Sync,
    /// Renaming it over the file.
    Rename,
    /// Flushing the directory (fsync) so the rename is durable.
    SyncDirectory,
}

impl Step {
    /// What the step does, for messages.
    pub const fn describe(self) -> &'static str {
        match self {
            Self::Create => "cannot create the temporary file",
            Self::Write => "cannot write the temporary file",
            Self::Sync => "cannot flush the temporary file to the disk (fsync)",
            Self::Rename => "cannot rename the temporary file over the file",
            Self::SyncDirectory => "cannot flush the directory to the disk (fsync)",
        }
    }
}

/// The temporary file's name for `path` in this process.
fn temporary(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let n = TEMP_SERIAL.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}{TEMP_MARK}{}.{n}", std::process::id()))
}

/// Replaces `path` by `bytes` atomically and durably (see the module's doc). The file
/// gets `mode` (subject to the umask) when it is new; the rename keeps the temporary
/// file's mode.
pub fn write_atomically(
    path: &Path,
    bytes: &[u8],
    mode: u32,
) -> Result<(), (Step, std::io::Error)> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let tmp = temporary(path);
    let written = (|| {
        let mut file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(mode)
            .open(&tmp)
            .map_err(|e| (Step::Create, e))?;
        file.write_all(bytes).map_err(|e| (Step::Write, e))?;
        file.sync_all().map_err(|e| (Step::Sync, e))?;
        std::fs::rename(&tmp, path).map_err(|e| (Step::Rename, e))
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written?;
    File::open(&dir)
        .and_then(|d| d.sync_all())
        .map_err(|e| (Step::SyncDirectory, e))
}

/// Removes the temporary files [`write_atomically`] left in `dir` when its process was
/// killed before the rename (those of processes still running are left alone: they may
/// be saving). Returns how many it removed.
pub fn remove_stale_temporaries(dir: &Path) -> std::io::Result<usize> {
    let mut removed = 0;
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = temp_owner(&name) else {
            continue;
        };
        if pid != std::process::id() && !running(pid) {
            std::fs::remove_file(entry.path())?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// The process id in a temporary file's name (`.NAME.tmp.PID.N`), if it is one.
fn temp_owner(name: &str) -> Option<u32> {
    if !name.starts_with('.') {
        return None;
    }
    let (_, tail) = name.rsplit_once(TEMP_MARK)?;
    let (pid, serial) = tail.split_once('.')?;
    serial.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// Whether a process with this id exists (kill(2) with signal 0 checks without sending).
fn running(pid: u32) -> bool {
    let Ok(pid) = i32::try_from(pid) else {
        return false;
    };
    match nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid), None) {
        Ok(()) => true,
        // It exists but belongs to another user.
        Err(nix::errno::Errno::EPERM) => true,
        Err(_) => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("gantry-atomic-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_write_replaces_the_file_and_leaves_no_temporary() {
        let d = dir("replace");
        let f = d.join("a.params");
        write_atomically(&f, b"one\n", 0o640).unwrap();
        write_atomically(&f, b"two\n", 0o640).unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two\n");
        let names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.params")]);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_names_its_step() {
        let d = dir("fail");
        let f = d.join("a.params");
        write_atomically(&f, b"old\n", 0o640).unwrap();
        // A directory where the file should be: the rename fails, the temporary goes.
        let blocked = d.join("b.params");
        std::fs::create_dir(&blocked).unwrap();
        std::fs::write(blocked.join("x"), b"").unwrap();
        let (step, _) = write_atomically(&blocked, b"new\n", 0o640).unwrap_err();
        assert_eq!(step, Step::Rename);
        let (step, _) = write_atomically(&d.join("missing/c.params"), b"new\n", 0o640).unwrap_err();
        assert_eq!(step, Step::Create);
        assert_eq!(std::fs::read(&f).unwrap(), b"old\n");
        assert_eq!(remove_stale_temporaries(&d).unwrap(), 0);
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 2);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn stale_temporaries_of_dead_processes_are_removed_live_ones_kept() {
        let d = dir("stale");
        // No process has pid 2^22 + 1 (above Linux' pid_max limit of 2^22).
        let dead = d.join(format!(".x.params{TEMP_MARK}{}.0", (1u32 << 22) + 1));
        let mine = d.join(format!(".x.params{TEMP_MARK}{}.7", std::process::id()));
        let other = d.join("x.params");
        for f in [&dead, &mine, &other] {
            std::fs::write(f, b"half").unwrap();
        }
        assert_eq!(remove_stale_temporaries(&d).unwrap(), 1);
        assert!(!dead.exists() && mine.exists() && other.exists());
        assert_eq!(temp_owner("x.params"), None);
        assert_eq!(temp_owner(".x.params.tmp.12.3"), Some(12));
        let _ = std::fs::remove_dir_all(&d);
    }
}
