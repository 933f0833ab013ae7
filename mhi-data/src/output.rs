//! Output folders a command owns: made whole or not at all, one writer at a time, never mixed
//! with what the user had.
//!
//! The rules every command that writes a folder follows:
//!
//! - **Ownership.** A folder a command made holds a marker, [`OWNER_MARKER`], naming the kind of
//!   output. A folder that is neither new, empty nor marked with the same kind is refused, with
//!   or without `--overwrite`: an overwrite only ever replaces an output of the same kind that an
//!   mhi command made, never files a user put there.
//! - **Whole or nothing** ([`StagedDir`]). The new output is built beside the folder, as
//!   `.NAME.partial-PID`, and swapped into place in one atomic rename when it is complete; the
//!   old output goes away only after that. An interrupted command leaves the old output or the
//!   new one, never a mix; its partial folder is found, named and removed by the next run.
//! - **One writer.** The marked folder's [`LOCK_FILE`] holds the writer's pid under an advisory
//!   lock (released by the system when the process ends, so a lock left by a killed process is
//!   stale and taken over); a second writer gets an error that names the first.
//! - **Links.** A symbolic link given as the folder itself is followed (the user named it);
//!   files are never written through a link found inside a folder: [`crate::write_atomic`]
//!   replaces the link.

use std::fs::File;
use std::io::{Read as _, Write as _};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// The marker file of a folder an mhi command made.
pub const OWNER_MARKER: &str = ".mhi-output.json";
/// The lock file of a marked folder: the writer's pid, under an advisory lock.
pub const LOCK_FILE: &str = ".mhi-lock";

/// What [`OWNER_MARKER`] records.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Eq)]
pub struct Marker {
    /// The kind of output (`"eval report"`, `"training run"`, …).
    pub kind: String,
    /// Whether the output was finished; `false` while it is written.
    pub complete: bool,
}

/// Read a folder's marker, if it has one.
pub fn read_marker(dir: &Path) -> Option<Marker> {
    let p = dir.join(OWNER_MARKER);
    let meta = std::fs::symlink_metadata(&p).ok()?;
    if !meta.is_file() || meta.len() > 4096 {
        return None;
    }
    serde_json::from_slice(&std::fs::read(&p).ok()?).ok()
}

fn write_marker(dir: &Path, kind: &str, complete: bool) -> Result<()> {
    let m = Marker {
        kind: kind.to_string(),
        complete,
    };
    let json = serde_json::to_vec_pretty(&m).expect("a marker serialises");
    crate::write_atomic(&dir.join(OWNER_MARKER), &json)
}

/// A held lock on a folder's [`LOCK_FILE`]; released when dropped or when the process ends.
#[derive(Debug)]
pub struct DirLock {
    _file: File,
}

/// Take the writer's lock of `dir` (which must exist), or say who holds it.
pub fn lock_dir(dir: &Path, what: &str) -> Result<DirLock> {
    let p = dir.join(LOCK_FILE);
    if std::fs::symlink_metadata(&p).is_ok_and(|m| !m.is_file()) {
        return Err(Error::Dataset {
            path: p,
            fault: "is not a regular file (a link or a folder): an mhi lock file is never a link"
                .into(),
        });
    }
    let mut file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&p)
        .map_err(|e| Error::io(&p, e))?;
    match file.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => {
            let mut s = String::new();
            let _ = file.take(32).read_to_string(&mut s);
            let who = match s.trim().parse::<u32>() {
                Ok(pid) => format!("process {pid}"),
                Err(_) => "another process".to_string(),
            };
            return Err(Error::Dataset {
                path: dir.to_path_buf(),
                fault: format!(
                    "{who} is writing this {what} now (it holds {LOCK_FILE}); wait for it to finish or choose another folder"
                ),
            });
        }
        Err(std::fs::TryLockError::Error(e)) => return Err(Error::io(&p, e)),
    }
    file.set_len(0).map_err(|e| Error::io(&p, e))?;
    file.write_all(format!("{}\n", std::process::id()).as_bytes())
        .map_err(|e| Error::io(&p, e))?;
    Ok(DirLock { _file: file })
}

/// The name of an entry a user would recognise, for an error (at most a few, `…` after).
fn some_entries(dir: &Path) -> String {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .map(|e| crate::sanitize::for_terminal(&e.file_name().to_string_lossy()))
                .filter(|n| n != OWNER_MARKER && n != LOCK_FILE)
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    let more = names.len() > 3;
    names.truncate(3);
    format!("{}{}", names.join(", "), if more { ", …" } else { "" })
}

fn is_empty_dir(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|mut d| d.next().is_none())
}

/// What [`claim_dir`] found in the folder it claimed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Found {
    /// The folder did not exist or was empty.
    Nothing,
    /// A complete output of the same kind.
    Complete,
    /// An output of the same kind that its writer did not finish.
    Unfinished,
}

/// Resolve a folder path given by the user: a symbolic link to a folder is followed.
fn resolve_user_dir(dir: &Path) -> Result<PathBuf> {
    match std::fs::symlink_metadata(dir) {
        Ok(m) if m.file_type().is_symlink() => {
            std::fs::canonicalize(dir).map_err(|e| Error::io(dir, e))
        }
        _ => Ok(dir.to_path_buf()),
    }
}

/// Check that `dir` may hold an output of `kind`, create and mark it if it is new or empty,
/// and take its writer's lock. Nothing is removed here.
///
/// A folder holding anything without a marker of the same kind is refused (its files are the
/// user's); so is a folder that is not a folder.
pub fn claim_dir(dir: &Path, kind: &str) -> Result<(PathBuf, DirLock, Found)> {
    let dir = resolve_user_dir(dir)?;
    match std::fs::symlink_metadata(&dir) {
        Ok(m) if !m.is_dir() => {
            return Err(Error::Dataset {
                path: dir,
                fault: format!("exists and is not a folder: the {kind} needs a folder"),
            });
        }
        Ok(_) => {}
        Err(_) => std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?,
    }
    let found = match read_marker(&dir) {
        Some(m) if m.kind == kind => {
            if m.complete {
                Found::Complete
            } else {
                Found::Unfinished
            }
        }
        Some(m) => {
            return Err(Error::Dataset {
                path: dir,
                fault: format!(
                    "holds a {} made by another mhi command, not a {kind}; choose another folder",
                    crate::sanitize::for_terminal(&m.kind)
                ),
            });
        }
        None if is_empty_dir(&dir) => Found::Nothing,
        None => {
            return Err(Error::Dataset {
                path: dir.clone(),
                fault: format!(
                    "holds files no mhi command made ({}); a {kind} is written only into a new or empty folder or over a {kind} made before, so nothing of yours is replaced: choose another folder",
                    some_entries(&dir)
                ),
            });
        }
    };
    let lock = lock_dir(&dir, kind)?;
    if found == Found::Nothing {
        write_marker(&dir, kind, false)?;
    }
    Ok((dir, lock, found))
}

/// Mark a claimed folder complete (or not).
pub fn mark_dir(dir: &Path, kind: &str, complete: bool) -> Result<()> {
    write_marker(dir, kind, complete)
}

/// A folder output built aside and swapped into place whole: see the module documentation.
#[derive(Debug)]
pub struct StagedDir {
    kind: String,
    target: PathBuf,
    staging: PathBuf,
    locks: Option<[DirLock; 2]>,
    notes: Vec<String>,
    /// What `begin` found at the target (to undo its claim if the output is abandoned).
    found: Found,
    /// Whether the target folder did not exist before `begin`.
    created: bool,
}

impl StagedDir {
    /// Begin an output of `kind` at `target`. Refused when `target` holds anything but an
    /// output of the same kind, when it holds a complete one and `overwrite` is false, or when
    /// another process is writing it. Partial folders left beside it by interrupted runs are
    /// removed (and said so in [`StagedDir::notes`]).
    pub fn begin(target: &Path, kind: &str, overwrite: bool) -> Result<Self> {
        let created = std::fs::symlink_metadata(target).is_err();
        let (target, lock, found) = claim_dir(target, kind)?;
        let mut notes = Vec::new();
        match found {
            Found::Complete if !overwrite => {
                return Err(Error::Dataset {
                    path: target,
                    fault: format!(
                        "already holds a {kind}; pass --overwrite to replace it, or choose another folder"
                    ),
                });
            }
            Found::Complete => notes.push(format!(
                "{} holds a {kind}; it is replaced when the new one is complete",
                target.display()
            )),
            Found::Unfinished => notes.push(format!(
                "{} holds an unfinished {kind} (an earlier run was interrupted); it is replaced",
                target.display()
            )),
            Found::Nothing => {}
        }
        let parent = target
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf();
        let name = target
            .file_name()
            .ok_or_else(|| Error::Dataset {
                path: target.clone(),
                fault: "has no folder name".into(),
            })?
            .to_string_lossy()
            .into_owned();
        let prefix = format!(".{name}.partial-");
        // Partial folders of interrupted runs: ours (marked) and no longer locked.
        if let Ok(entries) = std::fs::read_dir(&parent) {
            for e in entries.flatten() {
                let n = e.file_name().to_string_lossy().into_owned();
                let p = e.path();
                if !n.starts_with(&prefix)
                    || !std::fs::symlink_metadata(&p).is_ok_and(|m| m.is_dir())
                    || read_marker(&p).is_none_or(|m| m.kind != kind)
                {
                    continue;
                }
                if let Ok(l) = lock_dir(&p, kind) {
                    drop(l);
                    std::fs::remove_dir_all(&p).map_err(|e| Error::io(&p, e))?;
                    notes.push(format!(
                        "removed {}, the partial {kind} of an interrupted run",
                        p.display()
                    ));
                }
            }
        }
        let staging = parent.join(format!("{prefix}{}", std::process::id()));
        if std::fs::symlink_metadata(&staging).is_ok() {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        std::fs::create_dir(&staging).map_err(|e| Error::io(&staging, e))?;
        write_marker(&staging, kind, false)?;
        let staging_lock = lock_dir(&staging, kind)?;
        Ok(Self {
            kind: kind.to_string(),
            target,
            staging,
            locks: Some([lock, staging_lock]),
            notes,
            found,
            created,
        })
    }

    /// Where the output is written while it is built.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Where the output will be once committed.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// What [`StagedDir::begin`] found and did, for the user.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Swap the finished output into place in one rename, then remove the old one.
    pub fn commit(mut self) -> Result<PathBuf> {
        write_marker(&self.staging, &self.kind, true)?;
        exchange(&self.staging, &self.target)?;
        // The staging path now holds the old output (ours: claimed at `begin`).
        std::fs::remove_dir_all(&self.staging).map_err(|e| Error::io(&self.staging, e))?;
        self.locks = None;
        Ok(self.target.clone())
    }
}

#[cfg(test)]
impl StagedDir {
    /// What a killed process leaves: its locks released by the system, nothing cleaned.
    fn killed(mut self) {
        self.locks = None;
    }
}

/// An output abandoned by an error (not a signal, which skips this): its partial folder goes,
/// and so does the claim on the target, which is left as it was found.
impl Drop for StagedDir {
    fn drop(&mut self) {
        if self.locks.is_none() {
            return;
        }
        let _ = std::fs::remove_dir_all(&self.staging);
        if self.found == Found::Nothing {
            let _ = std::fs::remove_file(self.target.join(OWNER_MARKER));
            let _ = std::fs::remove_file(self.target.join(LOCK_FILE));
            if self.created {
                let _ = std::fs::remove_dir(&self.target);
            }
        }
        self.locks = None;
    }
}

#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> Result<()> {
    use rustix::fs::{CWD, RenameFlags, renameat_with};
    match renameat_with(CWD, a, CWD, b, RenameFlags::EXCHANGE) {
        Ok(()) => Ok(()),
        // A file system without RENAME_EXCHANGE: two renames, the old output first aside.
        Err(rustix::io::Errno::INVAL | rustix::io::Errno::NOSYS) => exchange_two_renames(a, b),
        Err(e) => Err(Error::io(b, e.into())),
    }
}

#[cfg(not(target_os = "linux"))]
fn exchange(a: &Path, b: &Path) -> Result<()> {
    exchange_two_renames(a, b)
}

fn exchange_two_renames(a: &Path, b: &Path) -> Result<()> {
    let aside = a.with_extension("old");
    std::fs::rename(b, &aside).map_err(|e| Error::io(b, e))?;
    std::fs::rename(a, b).map_err(|e| Error::io(b, e))?;
    std::fs::rename(&aside, a).map_err(|e| Error::io(a, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_of_the_users_is_refused_even_with_overwrite() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        std::fs::create_dir(&out).unwrap();
        std::fs::write(out.join("frame.png"), "mine").unwrap();
        for overwrite in [false, true] {
            let e = StagedDir::begin(&out, "eval report", overwrite)
                .unwrap_err()
                .to_string();
            assert!(e.contains("no mhi command made (frame.png)"), "{e}");
        }
        assert_eq!(
            std::fs::read_to_string(out.join("frame.png")).unwrap(),
            "mine"
        );
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1);
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn an_output_appears_whole_and_replaces_only_its_own_kind() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        let s = StagedDir::begin(&out, "render", false).unwrap();
        std::fs::write(s.path().join("a.txt"), "1").unwrap();
        // Until the commit the folder holds nothing of the new output.
        assert!(!out.join("a.txt").exists());
        s.commit().unwrap();
        assert_eq!(std::fs::read_to_string(out.join("a.txt")).unwrap(), "1");
        let e = StagedDir::begin(&out, "render", false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--overwrite"), "{e}");
        let e = StagedDir::begin(&out, "eval report", true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("another mhi command"), "{e}");
        let s = StagedDir::begin(&out, "render", true).unwrap();
        std::fs::write(s.path().join("b.txt"), "2").unwrap();
        s.commit().unwrap();
        assert!(!out.join("a.txt").exists(), "the old output's files go");
        assert!(out.join("b.txt").exists());
        // Nothing but the output is left beside it.
        let names: Vec<_> = std::fs::read_dir(d.path())
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("out")]);
    }

    #[test]
    fn a_second_writer_is_refused_and_an_interrupted_run_is_cleaned() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        let first = StagedDir::begin(&out, "render", false).unwrap();
        let e = StagedDir::begin(&out, "render", true)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("process {}", std::process::id())),
            "{e}"
        );
        // The first run "dies": its locks go, its partial folder stays.
        let staging = first.path().to_path_buf();
        first.killed();
        assert!(staging.exists());
        let s = StagedDir::begin(&out, "render", false).unwrap();
        assert!(
            s.notes().iter().any(|n| n.contains("unfinished")),
            "{:?}",
            s.notes()
        );
        assert!(
            s.notes().iter().any(|n| n.contains("partial")),
            "the partial folder of the killed run is removed and said so: {:?}",
            s.notes()
        );
        s.commit().unwrap();
        assert!(read_marker(&out).unwrap().complete);
        // An error (not a kill) takes its partial folder and its claim on a new folder with it.
        let fresh = d.path().join("fresh");
        let s = StagedDir::begin(&fresh, "render", false).unwrap();
        let partial = s.path().to_path_buf();
        drop(s);
        assert!(!partial.exists() && !fresh.exists());
    }

    #[cfg(unix)]
    #[test]
    fn outputs_follow_the_umask() {
        use std::os::unix::fs::PermissionsExt as _;
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        let s = StagedDir::begin(&out, "render", false).unwrap();
        crate::write_atomic(&s.path().join("x.json"), b"{}").unwrap();
        s.commit().unwrap();
        // What the umask gives a file and a folder that std creates in the plain way.
        let plain_file = d.path().join("plain.txt");
        std::fs::write(&plain_file, "x").unwrap();
        let plain_dir = d.path().join("plain");
        std::fs::create_dir(&plain_dir).unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&out.join("x.json")), mode(&plain_file));
        assert_eq!(mode(&out), mode(&plain_dir));
    }
}
