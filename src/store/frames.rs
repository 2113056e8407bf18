//! Frame streams: the covariant vectors as MCAP, to a file, to standard output, and back.
//!
//! A frame file is written as `FILE.tmp`; at the end of every backward segment its chunk is
//! closed and the file fsynced, so that a killed backward stage can salvage every frame up to
//! its last progress record and continue. The finished file is renamed to `FILE`. A sweep
//! holds `FILE.lock` beside it from before it looks at the file to its end ([`lock`]): sweeps
//! of two runs may be given the same --out, and only one may write it.
//! Standard output carries the same MCAP stream without seeking, for shell pipes.
//!
//! Files and pipes alike hold the frames in the order the backward sweep forms them, newest
//! step first, and are read in that order.

use super::schema::{CHECKPOINT, FRAME};
use super::segment::{read_stream, ReadMode, RUN_METADATA};
use crate::error::{Error, Result};
use crate::stage::frame::Frame;
use mcap::records::{MessageHeader, Metadata};
use super::write_error::{Watched, Witness};
use mcap::write::{NoSeek, WriteOptions, Writer};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};

/// What a consumer of frames wants next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    Continue,
    /// The consumer is gone (closed pipe, early stop): end the stream cleanly.
    Stop,
}

/// Frames are not compressed, in files or in streams: covariant vectors of a chaotic system
/// are nearly random doubles. zstd (level 1) made a file of 201 frames at D = k = 792 4.6 %
/// smaller (924 against 967 MiB) for about 10 ms of a core per 5 MB frame, and the backward
/// stage took 10.4-11.0 s with it against 9.8-10.1 s without (2 threads, runs alternating).
/// Files written compressed by earlier builds read as before.
fn options(seekable: bool) -> WriteOptions {
    WriteOptions::new()
        .compression(None)
        .chunk_size(Some(8 << 20))
        .disable_seeking(!seekable)
        .profile("clv")
}

struct McapOut<W: Write + Seek> {
    writer: Writer<W>,
    channel: u16,
    sequence: u32,
    /// Keeps the OS error of a failed write beneath the writer.
    witness: Witness,
}

impl<W: Write + Seek> McapOut<W> {
    /// `w` writes through a writer `witness` watches.
    fn new(w: W, witness: &Witness, seekable: bool, metadata: &BTreeMap<String, String>) -> mcap::McapResult<Self> {
        let mut writer = options(seekable).create(w)?;
        let meta = Metadata { name: RUN_METADATA.into(), metadata: metadata.clone() };
        writer.write_metadata(&meta)?;
        let schema = writer.add_schema(FRAME.name, "jsonschema", FRAME.text.as_bytes())?;
        let channel = writer.add_channel(schema, FRAME.topic, "cbor", &BTreeMap::new())?;
        Ok(McapOut { writer, channel, sequence: 0, witness: witness.clone() })
    }

    fn write(&mut self, step: u64, data: &[u8]) -> mcap::McapResult<()> {
        self.sequence += 1;
        let header = MessageHeader { channel_id: self.channel, sequence: self.sequence, log_time: step, publish_time: step };
        self.writer.write_to_known_channel(&header, data)
    }
}


/// A frame file being written (as FILE.tmp until finished).
pub struct FrameFile {
    path: PathBuf,
    tmp: PathBuf,
    out: McapOut<BufWriter<Watched<super::fault::Output>>>,
    /// A second handle on the same file, for fsync while the writer owns the first.
    sync_handle: File,
    /// Frames written so far.
    pub frames: u64,
}

pub fn tmp_path(path: &Path) -> PathBuf {
    suffixed(path, ".tmp")
}

fn suffixed(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(suffix);
    path.with_file_name(name)
}

/// FILE.lock, the lock file of the frame file `path`; left behind only by a killed sweep.
pub fn lock_path(path: &Path) -> PathBuf {
    suffixed(path, ".lock")
}

/// Take the right to write the frame file `path` (and its FILE.tmp, FILE.tmp.old) for a
/// whole backward sweep: a lock on FILE.lock beside it ([`super::lock`]), removed when the
/// sweep is done. Two sweeps of different runs may name the same --out; of two at once, the
/// second is refused here, before it looks at or writes anything of the file.
pub fn lock(path: &Path) -> Result<super::lock::WriteLock> {
    let lock = lock_path(path);
    super::lock::take(&lock, path, "backward pass (or give this sweep another --out)", true, |e| Error::io(&lock, e))
}

/// Whether two frame streams' metadata describe the same run and backward sweep: their
/// run.json and backward.json agree but for the number of threads, which changes no number
/// (a sweep may be continued on a node with other cores), and for how the frame file was
/// named (the file compared is that file).
fn same_sweep(a: &BTreeMap<String, String>, b: &BTreeMap<String, String>) -> bool {
    let parsed = |m: &BTreeMap<String, String>, key: &str| -> Option<serde_json::Value> {
        let mut v: serde_json::Value = serde_json::from_str(m.get(key)?).ok()?;
        if let Some(config) = v.get_mut("config").and_then(|c| c.as_object_mut()) {
            config.remove("threads");
        }
        if let Some(options) = v.as_object_mut() {
            options.remove("frames_path");
        }
        Some(v)
    };
    ["run.json", "backward.json"].iter().all(|key| {
        let (x, y) = (parsed(a, key), parsed(b, key));
        x.is_some() && x == y
    })
}

/// The metadata a frame file (or an unfinished FILE.tmp) begins with, if it has any (an
/// unreadable one as empty).
pub fn metadata_of(path: &Path) -> Result<Option<BTreeMap<String, String>>> {
    const ENOUGH: &str = "clv: read up to the metadata";
    let mut found = None;
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let read = read_stream(path, std::io::BufReader::new(file), ReadMode::Salvage, |m| {
        if m.topic == RUN_METADATA {
            found = Some(serde_json::from_slice(m.data).unwrap_or_default());
        }
        Err(Error::Other(ENOUGH.into()))
    });
    match read {
        Err(Error::Other(msg)) if msg == ENOUGH => Ok(found),
        Err(e) => Err(e),
        Ok(_) => Ok(found),
    }
}

/// Whether the frame stream in `path` begins with the metadata of another sweep than
/// `metadata` describes ([`same_sweep`]); read only up to its metadata.
fn begins_with_other_metadata(path: &Path, metadata: &BTreeMap<String, String>) -> Result<bool> {
    Ok(metadata_of(path)?.is_some_and(|theirs| !same_sweep(&theirs, metadata)))
}

impl FrameFile {
    /// Start FILE.tmp in FILE's directory, made if missing (as a run directory or a report
    /// is); refuses if FILE exists, or FILE.tmp (the caller decides what to do with an
    /// interrupted sweep's, under [`lock`]). FILE.tmp is created only if it is not there, so
    /// that even where files cannot be locked two sweeps never write one file.
    pub fn create(path: &Path, metadata: &BTreeMap<String, String>) -> Result<Self> {
        if path.exists() {
            return Err(Error::Other(format!("{} already exists; refusing to overwrite it: choose another --out (or delete it yourself, if it is a frame file you no longer need)", path.display())));
        }
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        }
        let tmp = tmp_path(path);
        let file = match std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(file) => file,
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                return Err(Error::Other(format!(
                    "another clv process is writing {} (it holds {}); wait for it to finish or stop it, or give this sweep another --out \
                     (if no clv process is running, {} is left by an interrupted sweep: continue that one with `clv backward RUN --resume`, or delete the file to give it up)",
                    path.display(),
                    tmp.display(),
                    tmp.display()
                )));
            }
            Err(e) => return Err(Error::io(&tmp, e)),
        };
        let sync_handle = file.try_clone().map_err(|e| Error::io(&tmp, e))?;
        let witness = Witness::default();
        let out = McapOut::new(BufWriter::with_capacity(1 << 20, witness.watch(super::fault::Output(file))), &witness, true, metadata).map_err(|e| witness.mcap_error(&tmp, e))?;
        Ok(FrameFile { path: path.to_path_buf(), tmp, out, sync_handle, frames: 0 })
    }

    /// Continue an interrupted file: keep its first frames, those of the steps `keep` (newest
    /// first: all complete chunks up to the last progress record), rewrite them into a fresh
    /// FILE.tmp and append from there. The interrupted file must be this sweep's (its
    /// metadata `metadata`), and hold exactly those steps: frames of another run or sweep
    /// are never spliced in.
    /// The interrupted file is kept as FILE.tmp.old until the copy is synced, and a salvage
    /// that was itself interrupted starts again from that copy.
    ///
    /// A sweep killed after it renamed the finished FILE, before its progress record said
    /// so, left no FILE.tmp: FILE itself is then the interrupted file, if this sweep wrote it.
    /// `restart` is the command that starts the sweep over, for a file that cannot be continued.
    pub fn salvage(path: &Path, metadata: &BTreeMap<String, String>, keep: &[u64], restart: &str) -> Result<Self> {
        let tmp = tmp_path(path);
        let old = tmp.with_extension("tmp.old");
        if !old.exists() && !tmp.exists() && path.exists() {
            let mut theirs = StreamInfo::default();
            read_frames_with(path, |info| {
                theirs = info;
                Ok(())
            }, |_| Ok(Flow::Stop))?;
            let theirs: BTreeMap<String, String> = [("run.json", &theirs.run_json), ("backward.json", &theirs.backward_json)]
                .into_iter()
                .filter_map(|(k, v)| Some((k.to_string(), v.clone()?)))
                .collect();
            if !same_sweep(&theirs, metadata) {
                return Err(Error::Other(format!(
                    "{} exists but was written by another backward sweep, and the interrupted sweep's {} is missing; remove {} or choose another --out, and run without --resume to start over",
                    path.display(),
                    tmp.display(),
                    path.display()
                )));
            }
            std::fs::rename(path, &old).map_err(|e| Error::io(path, e))?;
        }
        if old.exists() {
            if tmp.exists() {
                std::fs::remove_file(&tmp).map_err(|e| Error::io(&tmp, e))?;
            }
        } else if !keep.is_empty() {
            if !tmp.exists() {
                return Err(Error::Other(format!(
                    "{} is gone, and with it the {} frames the interrupted sweep wrote: that sweep cannot be continued; give the command without --resume to start it over \
                     (a sweep started by a build before 2026-11-25 is continued from the directory it was started in: its record names the file relative to it)",
                    tmp.display(),
                    keep.len()
                )));
            }
            // Another sweep's file at this path (another run whose --out names it) is left
            // where it is, for that sweep to continue.
            if begins_with_other_metadata(&tmp, metadata)? {
                return Err(Error::Other(format!(
                    "{} holds the frames of another run or backward sweep (one whose --out names the same file), not this sweep's, which are gone: \
                     leave it for that sweep, and give this command without --resume and with another --out to start this sweep over",
                    tmp.display()
                )));
            }
            std::fs::rename(&tmp, &old).map_err(|e| Error::io(&tmp, e))?;
        } else if tmp.exists() {
            if begins_with_other_metadata(&tmp, metadata)? {
                return Err(Error::Other(format!(
                    "{} holds the frames of another run or backward sweep (one whose --out names the same file), not this sweep's: \
                     leave it for that sweep, and give this command without --resume and with another --out to start this sweep over",
                    tmp.display()
                )));
            }
            std::fs::remove_file(&tmp).map_err(|e| Error::io(&tmp, e))?;
        }
        super::fault::crash_point("salvage-moved");
        let mut file = FrameFile::create(path, metadata)?;
        if old.exists() {
            let give_up = format!(
                "it cannot be continued: delete {} (and {}, if it exists) and give the sweep again without --resume, which starts it over (`{restart}`; \
                 the frames before the damage would be recomputed on the way in any case)",
                old.display(),
                tmp.display()
            );
            let mut ours = false;
            read_stream(&old, std::io::BufReader::new(File::open(&old).map_err(|e| Error::io(&old, e))?), ReadMode::Salvage, |m| {
                if m.topic == RUN_METADATA {
                    let theirs: BTreeMap<String, String> = serde_json::from_slice(m.data).unwrap_or_default();
                    ours = same_sweep(&theirs, metadata);
                    if !ours {
                        return Err(Error::Other(format!(
                            "{} holds the frames of another run or backward sweep (its run.json or backward.json metadata differs from this sweep's): {give_up}",
                            old.display()
                        )));
                    }
                }
                if m.topic == FRAME.topic && (file.frames as usize) < keep.len() {
                    let want = keep[file.frames as usize];
                    if !ours || m.step != want {
                        return Err(Error::corrupt(&old, format!(
                            "its frame {} is of step {}, where this sweep's progress record expects step {want}{}; {give_up}",
                            file.frames + 1,
                            m.step,
                            if ours { "" } else { " (and the file does not begin with this sweep's metadata)" }
                        )));
                    }
                    file.write_raw(m.step, m.data)?;
                }
                Ok(())
            })?;
            if (file.frames as usize) < keep.len() {
                return Err(Error::corrupt(&old, format!("holds {} complete frames, the progress record says {}; {give_up}", file.frames, keep.len())));
            }
            file.sync()?;
            super::fault::crash_point("salvage-copied");
            std::fs::remove_file(&old).map_err(|e| Error::io(&old, e))?;
            super::segment::sync_dir(path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new(".")))?;
        }
        Ok(file)
    }

    fn write_raw(&mut self, step: u64, data: &[u8]) -> Result<()> {
        self.out.write(step, data).map_err(|e| self.out.witness.mcap_error(&self.tmp, e))?;
        self.frames += 1;
        Ok(())
    }

    pub fn write(&mut self, frame: &Frame) -> Result<()> {
        self.write_raw(frame.step, &frame.encode())
    }

    /// Close the current chunk and fsync: every frame so far survives a crash.
    pub fn sync(&mut self) -> Result<()> {
        self.out.writer.flush().map_err(|e| self.out.witness.mcap_error(&self.tmp, e))?;
        self.sync_handle.sync_all().map_err(|e| Error::io(&self.tmp, e))?;
        super::fault::crash_point("frames-synced");
        Ok(())
    }

    pub fn finish(mut self) -> Result<PathBuf> {
        self.out.writer.finish().map_err(|e| self.out.witness.mcap_error(&self.tmp, e))?;
        let file = self.out.writer.into_inner().into_inner().map_err(|e| Error::io(&self.tmp, e.into_error()))?.into_inner().into_inner();
        file.sync_all().map_err(|e| Error::io(&self.tmp, e))?;
        super::fault::crash_point("frames-finished");
        std::fs::rename(&self.tmp, &self.path).map_err(|e| Error::io(&self.path, e))?;
        super::fault::crash_point("frames-renamed");
        super::segment::sync_dir(self.path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new(".")))?;
        Ok(self.path)
    }
}

/// The frame stream on standard output.
pub struct FrameStdout {
    /// The stream until [`FrameStdout::finish`] ends it. A stream dropped unfinished (the
    /// sweep failed) is left as it is, cut short: mcap's writer would write the closing
    /// records when dropped, and a reader would take the stream for a whole one.
    out: Option<McapOut<NoSeek<BufWriter<Watched<std::io::Stdout>>>>>,
    /// The reader closed the pipe: nothing more can be written, and that is not an error.
    closed: bool,
}

impl Drop for FrameStdout {
    fn drop(&mut self) {
        // Every frame was flushed when it was written; what the writer still holds is only
        // what would close the stream.
        if let Some(out) = self.out.take() {
            std::mem::forget(out);
        }
    }
}

fn is_broken_pipe(e: &mcap::McapError, witness: &Witness) -> bool {
    let pipe = |io: &std::io::Error| io.kind() == std::io::ErrorKind::BrokenPipe;
    witness.os_error().is_some_and(|io| pipe(&io)) || matches!(e, mcap::McapError::Io(io) if pipe(io))
}

impl FrameStdout {
    pub fn new(metadata: &BTreeMap<String, String>) -> Result<Self> {
        let witness = Witness::default();
        let out = McapOut::new(NoSeek::new(BufWriter::with_capacity(1 << 20, witness.watch(std::io::stdout()))), &witness, false, metadata)
            .map_err(|e| witness.mcap_error(Path::new("<stdout>"), e))?;
        Ok(FrameStdout { out: Some(out), closed: false })
    }

    /// Write a frame and flush it (its own chunk), so the reader sees it at once; a closed
    /// pipe is `Flow::Stop`, not an error.
    pub fn write(&mut self, frame: &Frame) -> Result<Flow> {
        let Some(out) = self.out.as_mut().filter(|_| !self.closed) else {
            return Ok(Flow::Stop);
        };
        match out.write(frame.step, &frame.encode()).and_then(|_| out.writer.flush()) {
            Ok(()) => Ok(Flow::Continue),
            Err(e) if is_broken_pipe(&e, &out.witness) => {
                self.closed = true;
                Ok(Flow::Stop)
            }
            Err(e) => Err(out.witness.mcap_error(Path::new("<stdout>"), e)),
        }
    }

    /// Write the stream's closing records (summary and footer): whether the reader took
    /// them. Without them a reader finds the stream cut short.
    pub fn finish(mut self) -> Result<bool> {
        if self.closed {
            return Ok(false);
        }
        let Some(mut out) = self.out.take() else {
            return Ok(false);
        };
        // mcap's finish leaves the closing records in our buffer, whose flush on drop would
        // lose a failure: flushed here.
        let witness = out.witness.clone();
        let flushed = out.writer.finish().and_then(|_| Ok(out.writer.into_inner().into_inner().flush()?));
        match flushed {
            Ok(()) => Ok(true),
            Err(e) if is_broken_pipe(&e, &witness) => Ok(false),
            Err(e) => Err(witness.mcap_error(Path::new("<stdout>"), e)),
        }
    }
}

/// The description a frame stream carries: the run (run.json), its forward spectrum, and
/// the options of the backward stage that wrote it (none in streams before 2026-11-24).
#[derive(Clone, Debug, Default)]
pub struct StreamInfo {
    pub run_json: Option<String>,
    pub spectrum_json: Option<String>,
    pub backward_json: Option<String>,
}

impl StreamInfo {
    /// The metadata written at the head of a frame stream (read back by [`read_frames_with`]).
    pub fn metadata(&self) -> BTreeMap<String, String> {
        [("run.json", &self.run_json), ("spectrum.json", &self.spectrum_json), ("backward.json", &self.backward_json)]
            .into_iter()
            .filter_map(|(key, value)| value.clone().map(|v| (key.to_string(), v)))
            .collect()
    }
}

/// Whether the file ends as a whole MCAP file does, with the closing magic: a cheap check
/// for a file cut short, without reading its frames (`clv inspect FILE` checks those).
pub fn ends_whole(path: &Path) -> std::io::Result<bool> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path)?;
    let mut tail = [0u8; 8];
    if f.metadata()?.len() < 16 {
        return Ok(false);
    }
    f.seek(SeekFrom::End(-8))?;
    f.read_exact(&mut tail)?;
    Ok(&tail == b"\x89MCAP0\r\n")
}

/// The run directory of a frame file `file` whose sweep recorded it as `recorded`: FILE is
/// RUN_DIR/<recorded> when that path is relative (the run's own --out names).
pub fn run_dir_of(file: &Path, recorded: &Path) -> Option<std::path::PathBuf> {
    if !recorded.is_relative() {
        return None;
    }
    let mut dir = file.to_path_buf();
    for _ in recorded.components() {
        dir.pop();
    }
    (dir.join(recorded) == file).then_some(dir)
}

/// Read frames from a file, or from standard input when `source` is "-". `on_info` is
/// called with the stream's description before the first frame; `visit` for each frame
/// until it says stop. Returns the damage (a stream cut short) if any.
pub fn read_frames_with(
    source: &Path,
    mut on_info: impl FnMut(StreamInfo) -> Result<()>,
    mut visit: impl FnMut(Frame) -> Result<Flow>,
) -> Result<Option<String>> {
    let mut stop = false;
    let mut on_message = |m: super::segment::Message| -> Result<()> {
        if m.topic == RUN_METADATA {
            let map: BTreeMap<String, String> = serde_json::from_slice(m.data).map_err(|e| Error::corrupt(source, e.to_string()))?;
            return on_info(StreamInfo {
                run_json: map.get("run.json").cloned(),
                spectrum_json: map.get("spectrum.json").cloned(),
                backward_json: map.get("backward.json").cloned(),
            });
        }
        // A run's segment, given by name or piped in: checkpoints where frames were expected.
        if m.topic == CHECKPOINT.topic {
            let name = if source == Path::new("-") { "<stdin>".to_string() } else { source.display().to_string() };
            return Err(Error::Other(format!(
                "{name} is a segment of a run directory (checkpoints and R matrices), not a frame stream; make the frames with `clv backward RUN_DIR --out - | clv analyze - --out REPORT`"
            )));
        }
        if stop || m.topic != FRAME.topic {
            return Ok(());
        }
        let frame = Frame::decode(m.data).map_err(|e| Error::corrupt(source, format!("step {}: {e}", m.step)))?;
        if visit(frame)? == Flow::Stop {
            stop = true;
        }
        Ok(())
    };
    let report = if source == Path::new("-") {
        read_stream(Path::new("<stdin>"), std::io::stdin().lock(), ReadMode::Checked, &mut on_message)?
    } else {
        super::segment::read_segment(source, ReadMode::Checked, &mut on_message)?
    };
    Ok(report.damage)
}

/// [`read_frames_with`] without the stream description.
pub fn read_frames(source: &Path, visit: impl FnMut(Frame) -> Result<Flow>) -> Result<(Option<String>, Option<String>)> {
    let mut run_json = None;
    let damage = read_frames_with(source, |info| {
        run_json = info.run_json;
        Ok(())
    }, visit)?;
    Ok((run_json, damage))
}
