//! What a command may do to its output (`--out`): the one rule every
//! matseg command that writes files follows (docs/outputs.md).
//!
//! - An output never holds an input of the same command, nor lies inside
//!   one ([`check_apart`]).
//! - A folder is matseg's only when it carries the marker matseg wrote
//!   when it made it ([`MARKER_FILE`]); a staging folder or file of the
//!   same name without it is someone else's: refused, never removed.
//! - An output folder is written whole into `OUT.partial` and renamed into
//!   place ([`StagedOutput`]). An earlier output is replaced whole, and
//!   only when it holds nothing but what the same command wrote there (its
//!   marker lists every file), so a folder never mixes two runs.
//! - A folder that commands add to by design (a dataset, a texture
//!   library, a training run) is opened by [`SharedFolder`]: every name the
//!   command writes is checked before its first byte is written.
//! - Every file is written to a temporary name beside it and renamed into
//!   place ([`write_atomic`]), so a kill at any moment leaves the old file
//!   or the new one.

use serde::{Deserialize, Serialize};
use std::path::{Component, Path, PathBuf};

/// The marker matseg writes into each folder it makes for a command: JSON
/// naming the command and, for a finished output, every file it wrote.
pub const MARKER_FILE: &str = ".matseg-output";

/// An output refused or that could not be written, with the path at fault.
#[derive(Debug, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct OutputError {
    /// The output (or staging) path concerned.
    pub path: PathBuf,
    /// What is wrong, on one line.
    pub message: String,
}

impl OutputError {
    /// An error about `path`.
    pub fn new(path: impl Into<PathBuf>, message: impl ToString) -> Self {
        Self {
            path: path.into(),
            message: message.to_string(),
        }
    }
}

/// What the marker of a folder says.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Marker {
    /// The command that made the folder (`segment`, `generate`...).
    pub command: String,
    /// The process writing the folder, while it is being staged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub writer: Option<u32>,
    /// Every file of a finished output, relative to it, `/`-separated and
    /// sorted (empty for a folder commands add to).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<String>,
}

impl Marker {
    /// The marker of folder `dir`, when it has a readable one.
    pub fn read(dir: &Path) -> Option<Marker> {
        let text = std::fs::read(dir.join(MARKER_FILE)).ok()?;
        serde_json::from_slice(&text).ok()
    }

    /// Writes this marker into `dir` (atomically).
    pub fn write(&self, dir: &Path) -> Result<(), OutputError> {
        let path = dir.join(MARKER_FILE);
        let json = serde_json::to_vec_pretty(self).expect("a marker serialises");
        write_atomic(&path, &json)
            .map_err(|e| OutputError::new(&path, format!("cannot write: {e}")))
    }

    /// Whether the process that was writing under this marker may still be
    /// running (it is this process, or a process of that id exists).
    fn writer_running(&self) -> bool {
        self.writer.is_some_and(|pid| {
            pid == std::process::id() || Path::new("/proc").join(pid.to_string()).exists()
        })
    }
}

/// A folder output as a command line names it, as the path it is written
/// to: trailing slashes and `.` parts dropped, and a last part of `.` or
/// `..` resolved against the folders that exist, so that the folder's
/// `.partial` sibling ([`partial_folder`]) lies beside it, never inside it.
/// The file system's root and an empty path are refused.
pub fn output_folder(out: &Path) -> Result<PathBuf, OutputError> {
    let refused = || OutputError::new(out, "not a folder to write into: name the folder itself");
    let normal: PathBuf = out.components().collect();
    let named = matches!(normal.components().next_back(), Some(Component::Normal(_)));
    let resolved = if named {
        normal
    } else {
        let absolute = std::path::absolute(&normal).map_err(|e| OutputError::new(out, e))?;
        absolute
            .canonicalize()
            .map_err(|e| OutputError::new(out, e))?
    };
    if resolved.file_name().is_none() {
        return Err(refused());
    }
    Ok(resolved)
}

/// Where the folder `out` (as [`output_folder`] gives it) is staged before
/// it is renamed into place: `OUT.partial` beside it.
pub fn partial_folder(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

/// Where a file is written before it is renamed to `path`: `path` + `.tmp`.
/// Readers skip such names, so a half-written file is never taken as whole.
pub fn temporary_path(path: &Path) -> PathBuf {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    PathBuf::from(tmp)
}

/// Writes `bytes` to `path` through a temporary file renamed into place, so
/// a reader never sees a half-written file. The temporary name is
/// [`temporary_path`] plus this process's id and a counter, made new (a
/// file already of that name is never written into), so writers of the
/// same file in several processes (jobs of an array on shared storage) or
/// threads never write into each other's temporary file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let (tmp, mut file) = loop {
        let write = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut tmp = temporary_path(path).into_os_string();
        tmp.push(format!(".{}.{write}", std::process::id()));
        let tmp = PathBuf::from(tmp);
        match std::fs::File::create_new(&tmp) {
            Ok(file) => break (tmp, file),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    };
    let written = file.write_all(bytes).and_then(|()| {
        drop(file);
        std::fs::rename(&tmp, path)
    });
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// `path` made absolute with every part that exists resolved (links,
/// `.`, `..`), the parts that do not yet exist appended as given; what two
/// names of one place have in common.
fn resolved(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut existing = absolute.clone();
    // The parts that do not exist, last first.
    let mut rest: Vec<std::ffi::OsString> = Vec::new();
    loop {
        if let Ok(real) = existing.canonicalize() {
            let mut whole = real;
            for part in rest.iter().rev() {
                if part == ".." {
                    whole.pop();
                } else if part != "." {
                    whole.push(part);
                }
            }
            return whole;
        }
        let Some(last) = existing.components().next_back() else {
            return absolute;
        };
        let part = last.as_os_str().to_owned();
        if !existing.pop() {
            return absolute;
        }
        rest.push(part);
    }
}

/// Refuses an output `out` that holds any of `inputs` (a photo, a frame
/// folder, a benchmark, a selection file) or lies inside one, naming both
/// paths; inputs that do not exist are left to the command to refuse.
pub fn check_apart(out: &Path, inputs: &[&Path]) -> Result<(), OutputError> {
    let out_at = resolved(out);
    let staging_at = partial_folder(&out_at);
    for input in inputs.iter().filter(|i| i.exists()) {
        let input_at = resolved(input);
        let message = if input_at == out_at {
            format!("is the input {}: choose another --out", input.display())
        } else if input_at.starts_with(&out_at) || input_at.starts_with(&staging_at) {
            format!(
                "holds the input {}: choose an --out outside the inputs",
                input.display()
            )
        } else if out_at.starts_with(&input_at) {
            format!(
                "lies inside the input {}: choose an --out outside the inputs",
                input.display()
            )
        } else {
            continue;
        };
        return Err(OutputError::new(out, message));
    }
    Ok(())
}

/// Refuses the output file `out` of a command whose inputs are `inputs`
/// when it is one of them (or inside one), when it is a folder, or when a
/// file is there that `written_by_matseg` does not recognise as one
/// matseg wrote: only matseg's own earlier output is replaced (by
/// [`write_atomic`]).
pub fn check_file_output(
    out: &Path,
    inputs: &[&Path],
    written_by_matseg: &dyn Fn(&Path) -> bool,
) -> Result<(), OutputError> {
    check_apart(out, inputs)?;
    match out.symlink_metadata() {
        Ok(meta) if meta.is_dir() => {
            Err(OutputError::new(out, "is a folder: name the file to write"))
        }
        Ok(_) if !written_by_matseg(out) => Err(OutputError::new(
            out,
            "holds a file matseg did not write: move it or choose another --out",
        )),
        _ => Ok(()),
    }
}

/// Every file below `dir` (the marker aside), relative to it,
/// `/`-separated and sorted; a link counts as a file and is not followed.
fn files_below(dir: &Path) -> std::io::Result<Vec<String>> {
    fn walk(dir: &Path, prefix: &str, out: &mut Vec<String>) -> std::io::Result<()> {
        for entry in std::fs::read_dir(dir)? {
            let entry = entry?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let relative = format!("{prefix}{name}");
            if entry.file_type()?.is_dir() {
                walk(&entry.path(), &format!("{relative}/"), out)?;
            } else if relative != MARKER_FILE {
                out.push(relative);
            }
        }
        Ok(())
    }
    let mut files = Vec::new();
    walk(dir, "", &mut files)?;
    files.sort();
    Ok(files)
}

/// The first entry of `dir` in name order (its marker aside).
fn first_entry(dir: &Path) -> Option<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n != MARKER_FILE)
        .collect();
    names.sort();
    names.into_iter().next()
}

/// Why the existing `out` may not be replaced by a new output of
/// `command`, if it may not: it must be absent, an empty folder, or a
/// folder whose marker is `command`'s and lists every file it holds.
fn replace_refusal(out: &Path, command: &str) -> Option<String> {
    let Ok(meta) = out.symlink_metadata() else {
        return None;
    };
    if !meta.is_dir() {
        return Some("is not a folder (a file, or a link): choose another --out".into());
    }
    let Some(marker) = Marker::read(out) else {
        let first = first_entry(out)?;
        return Some(format!(
            "holds {first:?}, which matseg did not write (only an earlier `matseg {command}` output is replaced): choose another --out"
        ));
    };
    if marker.command != command {
        return Some(format!(
            "holds the output of `matseg {}` (only an earlier `matseg {command}` output is replaced): choose another --out",
            marker.command
        ));
    }
    let files = match files_below(out) {
        Ok(files) => files,
        Err(e) => return Some(format!("cannot be listed: {e}")),
    };
    files
        .into_iter()
        .find(|f| marker.files.binary_search(f).is_err())
        .map(|foreign| {
            format!(
                "holds {foreign:?}, which `matseg {command}` did not write (only an earlier output is replaced whole): move it or choose another --out"
            )
        })
}

/// Makes the staging folder `staging` of `command`: an earlier one is
/// removed only when it carries matseg's marker and its writer has ended.
fn make_staging(staging: &Path, command: &str) -> Result<(), OutputError> {
    clear_staging(staging)?;
    std::fs::create_dir(staging).map_err(|e| cannot_write(staging, e))?;
    own_marker(command).write(staging)
}

/// As [`make_staging`], the folder marked from the moment it has its name:
/// made under a new name beside it, marked there and renamed, so a run
/// killed in between leaves no unmarked folder in its place to block the
/// next run (what it leaves beside it is in no one's way).
fn make_staging_marked(staging: &Path, command: &str) -> Result<(), OutputError> {
    clear_staging(staging)?;
    let begun = (0u32..)
        .map(|n| {
            let mut name = temporary_path(staging).into_os_string();
            name.push(format!(".{}.{n}", std::process::id()));
            PathBuf::from(name)
        })
        .find_map(|begun| match std::fs::create_dir(&begun) {
            // A name already there is never written into.
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => None,
            made => Some(made.map(|()| begun)),
        })
        .expect("a new name")
        .map_err(|e| cannot_write(staging, e))?;
    own_marker(command).write(&begun)?;
    std::fs::rename(&begun, staging).map_err(|e| cannot_write(staging, e))
}

/// This process's marker of `command`.
fn own_marker(command: &str) -> Marker {
    Marker {
        command: command.to_string(),
        writer: Some(std::process::id()),
        files: Vec::new(),
    }
}

fn cannot_write(path: &Path, e: std::io::Error) -> OutputError {
    OutputError::new(path, format!("cannot write: {e}"))
}

/// Clears the way for the staging folder `staging`: an earlier one is
/// removed only when it carries matseg's marker and its writer has ended;
/// the folder it goes in is made when missing.
fn clear_staging(staging: &Path) -> Result<(), OutputError> {
    if staging.symlink_metadata().is_ok() {
        match Marker::read(staging) {
            Some(marker) if marker.writer_running() && marker.writer != Some(std::process::id()) => {
                return Err(OutputError::new(
                    staging,
                    format!(
                        "another matseg (process {}) is writing here: wait for it, or choose another --out",
                        marker.writer.unwrap_or_default()
                    ),
                ))
            }
            Some(_) if staging.is_dir() => {
                std::fs::remove_dir_all(staging).map_err(|e| cannot_write(staging, e))?
            }
            _ => {
                return Err(OutputError::new(
                    staging,
                    "is in the way of matseg's staging folder and was not made by matseg (no marker): move it or choose another --out",
                ))
            }
        }
    }
    if let Some(parent) = staging.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .map_err(|e| OutputError::new(parent, format!("cannot create: {e}")))?;
    }
    Ok(())
}

/// An output folder of one command written whole: the command writes into
/// [`StagedOutput::dir`] (`OUT.partial`), and [`StagedOutput::finish`]
/// puts it in place of `OUT`; dropped unfinished (an error, a panic), the
/// staging folder is removed and `OUT` is left as it was.
pub struct StagedOutput {
    out: PathBuf,
    staging: PathBuf,
    command: String,
    finished: bool,
}

impl StagedOutput {
    /// Starts the output `out` of `command` (`segment`, `apply`...),
    /// whose inputs are `inputs`. Refused, before anything is written, when
    /// `out` and an input overlap ([`check_apart`]), when `out` holds
    /// anything but an earlier output of the same command, or when
    /// `OUT.partial` exists without matseg's marker.
    pub fn begin(out: &Path, command: &str, inputs: &[&Path]) -> Result<Self, OutputError> {
        let out = output_folder(out)?;
        check_apart(&out, inputs)?;
        if let Some(why) = replace_refusal(&out, command) {
            return Err(OutputError::new(&out, why));
        }
        let staging = partial_folder(&out);
        make_staging_marked(&staging, command)?;
        Ok(Self {
            out,
            staging,
            command: command.to_string(),
            finished: false,
        })
    }

    /// The folder to write into (the staging folder).
    pub fn dir(&self) -> &Path {
        &self.staging
    }

    /// The output folder, as it is written to.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// Marks the staged folder with every file it holds and puts it in
    /// place of the output: swapped with an earlier output in one step
    /// where the file system can, which is then removed.
    pub fn finish(mut self) -> Result<PathBuf, OutputError> {
        let files = files_below(&self.staging)
            .map_err(|e| OutputError::new(&self.staging, format!("cannot be listed: {e}")))?;
        Marker {
            command: self.command.clone(),
            writer: None,
            files,
        }
        .write(&self.staging)?;
        if let Some(why) = replace_refusal(&self.out, &self.command) {
            return Err(OutputError::new(&self.out, why));
        }
        put_in_place(&self.staging, &self.out)?;
        self.finished = true;
        Ok(self.out.clone())
    }
}

impl Drop for StagedOutput {
    fn drop(&mut self) {
        if !self.finished {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

/// Renames the folder `staged` to `out`, replacing `out` when it exists
/// (checked as replaceable by the caller): exchanged in one step where the
/// system can (Linux), so a kill leaves the old output or the new one.
fn put_in_place(staged: &Path, out: &Path) -> Result<(), OutputError> {
    let failed = |e: std::io::Error| OutputError::new(out, format!("cannot put in place: {e}"));
    if out.symlink_metadata().is_err() {
        return std::fs::rename(staged, out).map_err(failed);
    }
    if exchange(staged, out).is_ok() {
        // `staged` now holds the earlier output.
        return std::fs::remove_dir_all(staged).map_err(failed);
    }
    std::fs::remove_dir_all(out).map_err(failed)?;
    std::fs::rename(staged, out).map_err(failed)
}

/// Swaps two paths in one step (Linux's `renameat2` with
/// `RENAME_EXCHANGE`); an error where the system or file system cannot.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| {
        CString::new(p.as_os_str().as_bytes())
            .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))
    };
    let (a, b) = (c(a)?, c(b)?);
    // SAFETY: both paths are valid NUL-terminated strings that outlive the call.
    let done = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            a.as_ptr(),
            libc::AT_FDCWD,
            b.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if done == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Swapping in one step is not available here: the caller removes, then renames.
#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> std::io::Result<()> {
    Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
}

/// A folder a command adds to by design and comes back to (a dataset it
/// resumes, a texture or material library, a training run, a cache): it
/// is the command's when it is new or empty, when it carries the
/// command's own sign (its marker, or a file only it writes, such as a
/// dataset's manifest), or when everything in it is something the command
/// writes. Names the command is about to write are checked with
/// [`SharedFolder::claim`] before their first byte.
pub struct SharedFolder {
    dir: PathBuf,
}

/// What a command that adds to a shared folder recognises as its own.
pub struct Layout<'a> {
    /// The command (`generate`, `textures`...).
    pub command: &'a str,
    /// What tells that a folder is the command's.
    pub sign: Sign<'a>,
    /// Whether an entry of the folder (by its path) is one the command
    /// writes, whole or in part: a folder without the command's sign is
    /// the command's only when all its entries are.
    pub owns: &'a dyn Fn(&Path) -> bool,
}

/// What tells that a shared folder is a command's.
pub enum Sign<'a> {
    /// matseg's marker, written when the folder is opened.
    Marker,
    /// A file of the command's own (a dataset's manifest), which this
    /// tells is in the folder; no marker is written.
    Own(&'a dyn Fn(&Path) -> bool),
    /// Nothing but its entries (a training run's new folder); no marker
    /// is written.
    Entries,
}

impl SharedFolder {
    /// Opens `out` for `layout.command`, whose inputs are `inputs`: made
    /// when absent and marked with matseg's marker when the command's own
    /// sign is the marker. Refused, before anything is written, as
    /// [`SharedFolder::check`] says.
    pub fn open(out: &Path, layout: &Layout<'_>, inputs: &[&Path]) -> Result<Self, OutputError> {
        let dir = Self::check(out, layout, inputs)?;
        let marked = Marker::read(&dir).is_some();
        std::fs::create_dir_all(&dir)
            .map_err(|e| OutputError::new(&dir, format!("cannot create: {e}")))?;
        if !marked && matches!(layout.sign, Sign::Marker) {
            Marker {
                command: layout.command.to_string(),
                ..Marker::default()
            }
            .write(&dir)?;
        }
        Ok(Self { dir })
    }

    /// Whether `out` may be opened for `layout.command`, writing nothing:
    /// refused when `out` and an input overlap, when it carries another
    /// command's marker, or when, carrying neither the command's marker nor
    /// its own sign, it holds something the command does not write. The
    /// folder as it is written to.
    pub fn check(
        out: &Path,
        layout: &Layout<'_>,
        inputs: &[&Path],
    ) -> Result<PathBuf, OutputError> {
        let dir = output_folder(out)?;
        check_apart(&dir, inputs)?;
        if dir.symlink_metadata().is_ok() && !dir.is_dir() {
            return Err(OutputError::new(
                &dir,
                "is not a folder (a file, or a link): choose another --out",
            ));
        }
        let marked = Marker::read(&dir);
        if let Some(marker) = &marked {
            if marker.command != layout.command {
                return Err(OutputError::new(
                    &dir,
                    format!(
                        "holds the output of `matseg {}`, not of `matseg {}`: choose another --out",
                        marker.command, layout.command
                    ),
                ));
            }
        }
        let signed = marked.is_some()
            || match layout.sign {
                Sign::Own(signed) => signed(&dir),
                Sign::Marker | Sign::Entries => false,
            };
        if !signed {
            if let Some(foreign) = foreign_entry(&dir, layout.owns) {
                return Err(OutputError::new(
                    &dir,
                    format!(
                        "holds {foreign:?}, which `matseg {}` does not write: choose another --out",
                        layout.command
                    ),
                ));
            }
        }
        Ok(dir)
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Checks the entries `names` the command is about to write (or
    /// replace) in the folder: each must be absent or pass `owns`; the
    /// first that does not is refused, naming it.
    pub fn claim<'a>(
        &self,
        names: impl IntoIterator<Item = &'a Path>,
        owns: &dyn Fn(&Path) -> bool,
    ) -> Result<(), OutputError> {
        for name in names {
            let path = self.dir.join(name);
            if path.symlink_metadata().is_ok() && !owns(&path) {
                return Err(OutputError::new(
                    &path,
                    "is in the way of a file matseg writes and was not made by matseg: move it or choose another --out",
                ));
            }
        }
        Ok(())
    }
}

/// The first entry of `dir` (in name order, its marker aside) that `owns`
/// does not recognise; none when `dir` does not exist or holds only owned
/// entries.
fn foreign_entry(dir: &Path, owns: &dyn Fn(&Path) -> bool) -> Option<String> {
    let listing = std::fs::read_dir(dir).ok()?;
    let mut names: Vec<(String, PathBuf)> = listing
        .filter_map(|e| e.ok())
        .map(|e| (e.file_name().to_string_lossy().into_owned(), e.path()))
        .filter(|(name, _)| name != MARKER_FILE)
        .collect();
    names.sort();
    names
        .into_iter()
        .find(|(_, path)| !owns(path))
        .map(|(name, _)| name)
}

/// Stages a folder that is renamed into a shared folder when complete
/// (a dataset's sample, a library's material): an earlier `staging` is
/// removed only when it carries matseg's marker of `command` and its
/// writer has ended; anything else of that name is refused. The new
/// staging folder carries the marker; [`unmark`] takes it out.
pub fn stage_folder(staging: &Path, command: &str) -> Result<(), OutputError> {
    make_staging(staging, command)
}

/// Takes matseg's marker out of a folder staged by [`stage_folder`], once
/// it is complete.
pub fn unmark(dir: &Path) -> Result<(), OutputError> {
    let path = dir.join(MARKER_FILE);
    match std::fs::remove_file(&path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(OutputError::new(&path, format!("cannot remove: {e}")))
        }
        _ => Ok(()),
    }
}

/// Whether `dir` is a folder that carries matseg's marker of `command`.
pub fn is_marked(dir: &Path, command: &str) -> bool {
    Marker::read(dir).is_some_and(|m| m.command == command)
}

/// Whether `dir` is a folder holding nothing but entries whose names
/// `name_ok` accepts (its marker aside): a folder a command recognises by
/// the names it writes there.
pub fn holds_only(dir: &Path, name_ok: &dyn Fn(&str) -> bool) -> bool {
    dir.is_dir()
        && std::fs::read_dir(dir).is_ok_and(|listing| {
            listing.filter_map(|e| e.ok()).all(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name == MARKER_FILE || name_ok(&name)
            })
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every file below `dir` with its bytes, the marker included.
    fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
        let mut files: Vec<(String, Vec<u8>)> = files_below(dir)
            .unwrap()
            .into_iter()
            .map(|f| {
                let bytes = std::fs::read(dir.join(&f)).unwrap();
                (f, bytes)
            })
            .collect();
        if let Ok(marker) = std::fs::read(dir.join(MARKER_FILE)) {
            files.push((MARKER_FILE.into(), marker));
        }
        files
    }

    fn write(path: &Path, text: &str) {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }

    /// A finished output of `command` in `out` holding `files`.
    fn output(out: &Path, command: &str, files: &[&str]) {
        let staged = StagedOutput::begin(out, command, &[]).unwrap();
        for f in files {
            write(&staged.dir().join(f), f);
        }
        staged.finish().unwrap();
    }

    #[test]
    fn output_folders_have_their_partial_folder_beside_them() {
        let cwd = std::env::current_dir().unwrap();
        for (given, written) in [
            ("out", PathBuf::from("out")),
            ("out/", PathBuf::from("out")),
            ("a/out//", PathBuf::from("a/out")),
            ("./a/./out/.", PathBuf::from("./a/out")),
            (".", cwd.clone()),
            ("./", cwd.clone()),
            ("..", cwd.parent().unwrap().to_path_buf()),
        ] {
            let out = output_folder(Path::new(given)).unwrap();
            assert_eq!(out, written, "{given}");
            let partial = partial_folder(&out);
            assert_eq!(partial.parent(), out.parent(), "{given}: beside it");
            assert!(partial.to_string_lossy().ends_with(".partial"), "{given}");
        }
        for refused in ["/", "", "/.."] {
            assert!(output_folder(Path::new(refused)).is_err(), "{refused}");
        }
    }

    #[test]
    fn concurrent_writers_of_one_file_all_succeed_and_leave_it_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dataset.json");
        let content = vec![b'x'; 1 << 20];
        std::thread::scope(|scope| {
            for _ in 0..8 {
                scope.spawn(|| {
                    for _ in 0..10 {
                        write_atomic(&path, &content).unwrap();
                    }
                });
            }
        });
        assert_eq!(std::fs::read(&path).unwrap(), content);
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "no temporary file left");
    }

    #[test]
    fn outputs_and_inputs_never_overlap() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        write(&root.join("photos/a.jpg"), "a");
        write(&root.join("other/b.jpg"), "b");
        let photos = root.join("photos");
        let photo = photos.join("a.jpg");
        let refused = |out: PathBuf, input: &Path, says: &str| {
            let e = check_apart(&out, &[input]).unwrap_err();
            assert_eq!(e.path, out);
            assert!(e.message.contains(says), "{out:?} {input:?}: {e}");
            assert!(e.message.contains(&input.display().to_string()), "{e}");
        };
        refused(photos.clone(), &photo, "holds the input");
        refused(root.to_path_buf(), &photo, "holds the input");
        refused(photos.join("masks"), &photos, "lies inside the input");
        refused(photo.clone(), &photo, "is the input");
        // Other names of the same places.
        refused(root.join("other/../photos"), &photo, "holds the input");
        refused(root.join("photos/./new/deeper"), &photos, "lies inside");
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(&photos, root.join("link")).unwrap();
            refused(root.join("link"), &photo, "holds the input");
        }
        // The staging folder beside an output is part of it.
        let staged = root.join("photos-out.partial/c.jpg");
        write(&staged, "c");
        refused(root.join("photos-out"), &staged, "holds the input");
        check_apart(&root.join("out"), &[&photo, &root.join("other")]).unwrap();
        check_apart(&root.join("photos2"), &[&photos]).unwrap();
        check_apart(&root.join("out"), &[&root.join("missing.jpg")]).unwrap();
    }

    #[test]
    fn an_earlier_output_is_replaced_whole_and_only_by_its_own_command() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        output(
            &out,
            "segment",
            &["mask_0.png", "mask_1.png", "sub/labels.png"],
        );
        let marker = Marker::read(&out).unwrap();
        assert_eq!(marker.command, "segment");
        assert_eq!(marker.files, ["mask_0.png", "mask_1.png", "sub/labels.png"]);
        assert_eq!(marker.writer, None);
        // A second run replaces it whole: no file of the first is left.
        output(&out, "segment", &["mask_0.png"]);
        assert_eq!(files_below(&out).unwrap(), ["mask_0.png"]);
        assert!(!partial_folder(&out).exists());
        // Another command's output is refused, and left as it was.
        let before = snapshot(&out);
        let e = StagedOutput::begin(&out, "apply", &[]).err().unwrap();
        assert!(e.message.contains("`matseg segment`"), "{e}");
        assert_eq!(snapshot(&out), before);
        // A file added by someone else is named, and nothing is touched.
        write(&out.join("notes/mine.txt"), "mine");
        let before = snapshot(&out);
        let e = StagedOutput::begin(&out, "segment", &[]).err().unwrap();
        assert!(e.message.contains("notes/mine.txt"), "{e}");
        assert_eq!(snapshot(&out), before);
        assert!(!partial_folder(&out).exists());
    }

    #[test]
    fn a_folder_matseg_did_not_make_is_never_replaced_or_removed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        write(&out.join("photo.jpg"), "photo");
        let e = StagedOutput::begin(&out, "segment", &[]).err().unwrap();
        assert!(e.message.contains("photo.jpg"), "{e}");
        // A foreign OUT.partial is refused and kept.
        let other = dir.path().join("other");
        let staging = partial_folder(&other);
        write(&staging.join("keep.txt"), "keep");
        let e = StagedOutput::begin(&other, "segment", &[]).err().unwrap();
        assert_eq!(e.path, staging);
        assert_eq!(std::fs::read(staging.join("keep.txt")).unwrap(), b"keep");
        // A file where the staging folder goes, too.
        let third = dir.path().join("third");
        write(&partial_folder(&third), "a file");
        assert!(StagedOutput::begin(&third, "segment", &[]).is_err());
        assert_eq!(std::fs::read(partial_folder(&third)).unwrap(), b"a file");
        // A file named as the output.
        write(&dir.path().join("file"), "f");
        assert!(StagedOutput::begin(&dir.path().join("file"), "maps", &[]).is_err());
        // An empty folder is the user's way of saying where: written into.
        let empty = dir.path().join("empty");
        std::fs::create_dir(&empty).unwrap();
        output(&empty, "maps", &["colour.png"]);
        assert_eq!(files_below(&empty).unwrap(), ["colour.png"]);
    }

    #[test]
    fn a_staging_folder_left_by_matseg_is_reused_unless_its_writer_runs() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let staging = partial_folder(&out);
        // A killed run's staging folder: its writer has ended.
        std::fs::create_dir(&staging).unwrap();
        write(&staging.join("half.png"), "half");
        let ended = Marker {
            command: "maps".into(),
            writer: Some(u32::MAX),
            files: Vec::new(),
        };
        ended.write(&staging).unwrap();
        output(&out, "maps", &["colour.png"]);
        assert_eq!(files_below(&out).unwrap(), ["colour.png"]);
        // One being written by a running process is refused.
        std::fs::create_dir(&staging).unwrap();
        let running = Marker {
            writer: Some(1),
            ..ended
        };
        running.write(&staging).unwrap();
        let e = StagedOutput::begin(&out, "maps", &[]).err().unwrap();
        assert!(e.message.contains("process 1"), "{e}");
    }

    #[test]
    fn an_unfinished_output_leaves_the_earlier_one_as_it_was() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        output(&out, "track", &["track.json"]);
        let before = snapshot(&out);
        {
            let staged = StagedOutput::begin(&out, "track", &[]).unwrap();
            write(&staged.dir().join("track.json"), "new");
            // Dropped unfinished, as on an error.
        }
        assert_eq!(snapshot(&out), before);
        assert!(!partial_folder(&out).exists());
        // An output whose input it holds is refused before anything.
        let frames = out.join("frames");
        write(&frames.join("0001.png"), "frame");
        let e = StagedOutput::begin(&out, "track", &[&frames])
            .err()
            .unwrap();
        assert!(e.message.contains("holds the input"), "{e}");
        assert!(frames.join("0001.png").exists());
    }

    #[test]
    fn a_shared_folder_is_added_to_only_where_it_is_the_commands() {
        let dir = tempfile::tempdir().unwrap();
        let texture = |p: &Path| {
            let name = p.file_name().unwrap().to_string_lossy();
            name.ends_with(".jpg") || name == "records"
        };
        let layout = Layout {
            command: "textures",
            sign: Sign::Marker,
            owns: &texture,
        };
        let lib = dir.path().join("lib");
        let opened = SharedFolder::open(&lib, &layout, &[]).unwrap();
        assert!(is_marked(opened.dir(), "textures"));
        write(&lib.join("a__0.jpg"), "crop");
        write(&lib.join("notes.txt"), "mine");
        // Marked: the folder is the command's, a user's file beside.
        SharedFolder::open(&lib, &layout, &[]).unwrap();
        let e = opened
            .claim([Path::new("b__0.jpg"), Path::new("notes.txt")], &texture)
            .unwrap_err();
        assert!(e.path.ends_with("notes.txt"), "{e}");
        // Unmarked: only the command's own entries.
        let photos = dir.path().join("photos");
        write(&photos.join("x.jpg"), "photo");
        write(&photos.join("licenses.json"), "{}");
        let e = SharedFolder::open(&photos, &layout, &[]).err().unwrap();
        assert!(e.message.contains("licenses.json"), "{e}");
        assert!(!photos.join(MARKER_FILE).exists());
        // Another command's marked folder.
        let pbr = Layout {
            command: "pbr",
            ..layout
        };
        assert!(SharedFolder::open(&lib, &pbr, &[]).is_err());
        // A sign of the command's own (a manifest) instead of the marker.
        let signed = |d: &Path| d.join("dataset.json").is_file();
        let generate = Layout {
            command: "generate",
            sign: Sign::Own(&signed),
            owns: &|_: &Path| false,
        };
        let data = dir.path().join("data");
        write(&data.join("dataset.json"), "{}");
        write(&data.join("README"), "mine");
        SharedFolder::open(&data, &generate, &[]).unwrap();
        assert!(!data.join(MARKER_FILE).exists());
    }

    #[test]
    fn a_staged_folder_in_a_shared_one_carries_the_marker_until_complete() {
        let dir = tempfile::tempdir().unwrap();
        let staging = dir.path().join("00000001.partial");
        stage_folder(&staging, "generate").unwrap();
        assert!(is_marked(&staging, "generate"));
        unmark(&staging).unwrap();
        assert!(!staging.join(MARKER_FILE).exists());
        // Unmarked now: someone else's, as far as matseg can tell.
        assert!(stage_folder(&staging, "generate").is_err());
        assert!(holds_only(&staging, &|_| false));
        write(&staging.join("mask0.png"), "m");
        assert!(holds_only(&staging, &|n| n.starts_with("mask")));
        assert!(!holds_only(&staging, &|n| n == "meta.json"));
    }
}
