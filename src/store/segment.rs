//! Segment files: one MCAP file per run of consecutive checkpoints.
//!
//! The mcap writer cannot append, and a file cut short by a crash still yields its complete
//! chunks, so a segment is written under `NAME.mcap.tmp`, finished, fsynced and only then
//! renamed to its final name (`seg-FIRST-LAST.mcap`, the steps of its first message and its
//! last checkpoint), and the directory is fsynced. A finished segment is never rewritten; a
//! `.tmp` file is by construction an interrupted one. Readers go by the names; a file whose
//! steps are not those of its name is damage ([`super::run::SegmentFile::misnamed`]).

use super::schema::Schema;
use super::write_error::{Watched, Witness};
use crate::error::{Error, Result};
use mcap::records::{MessageHeader, Metadata, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::write::{WriteOptions, Writer};
use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::{BufWriter, Read};
use std::path::{Path, PathBuf};

/// Name of the MCAP metadata record holding the run description (run.json) in every file.
pub const RUN_METADATA: &str = "clv.run";

pub fn tmp_name(first_step: u64) -> String {
    format!("seg-{first_step:012}.mcap.tmp")
}

pub fn final_name(first_step: u64, last_step: u64) -> String {
    format!("seg-{first_step:012}-{last_step:012}.mcap")
}

/// (first, last) checkpoint steps from a finished segment's file name.
pub fn parse_final_name(name: &str) -> Option<(u64, u64)> {
    let core = name.strip_prefix("seg-")?.strip_suffix(".mcap")?;
    let (a, b) = core.split_once('-')?;
    Some((a.parse().ok()?, b.parse().ok()?))
}

pub struct SegmentWriter {
    dir: PathBuf,
    tmp: PathBuf,
    first_step: u64,
    last_checkpoint: Option<u64>,
    writer: Writer<BufWriter<Watched<super::fault::Output>>>,
    witness: Witness,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
    /// Bytes of message data written (before compression).
    pub bytes: u64,
    pub checkpoints: u64,
}

impl SegmentWriter {
    /// Start `seg-FIRST.mcap.tmp` in `dir`, refusing to overwrite anything.
    pub fn create(dir: &Path, first_step: u64, run_json: &str, schemas: &[&'static Schema]) -> Result<Self> {
        let tmp = dir.join(tmp_name(first_step));
        let file = File::options().write(true).create_new(true).open(&tmp).map_err(|e| Error::io(&tmp, e))?;
        // zstd on the writer thread alone (the mcap crate's default is a worker per core): the
        // writer is already off the simulation thread, and zstd's workers held 15-19 MB of job
        // buffers per segment that set the forward stage's peak RSS and moved it from run to
        // run (48-52 MB at D = k = 792; 35-38 MB without them, the same step time).
        let options = WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
            .compression_threads(0)
            .chunk_size(Some(4 << 20))
            .profile("clv");
        let witness = Witness::default();
        let mcap_err = |path: &Path, e| witness.mcap_error(path, e);
        let mut writer = options.create(BufWriter::with_capacity(1 << 20, witness.watch(super::fault::Output(file)))).map_err(|e| mcap_err(&tmp, e))?;
        let meta = Metadata { name: RUN_METADATA.into(), metadata: BTreeMap::from([("run.json".to_string(), run_json.to_string())]) };
        writer.write_metadata(&meta).map_err(|e| mcap_err(&tmp, e))?;
        let mut channels = BTreeMap::new();
        for s in schemas {
            let schema = writer.add_schema(s.name, "jsonschema", s.text.as_bytes()).map_err(|e| mcap_err(&tmp, e))?;
            let id = writer.add_channel(schema, s.topic, "cbor", &BTreeMap::new()).map_err(|e| mcap_err(&tmp, e))?;
            channels.insert(s.topic, id);
        }
        Ok(SegmentWriter { dir: dir.to_path_buf(), tmp, first_step, last_checkpoint: None, writer, witness, channels, sequence: 0, bytes: 0, checkpoints: 0 })
    }

    pub fn write(&mut self, topic: &str, step: u64, data: &[u8]) -> Result<()> {
        let channel_id = *self.channels.get(topic).ok_or_else(|| Error::Other(format!("no channel {topic:?} in this file")))?;
        self.sequence += 1;
        let header = MessageHeader { channel_id, sequence: self.sequence, log_time: step, publish_time: step };
        self.writer.write_to_known_channel(&header, data).map_err(|e| self.witness.mcap_error(&self.tmp, e))?;
        self.bytes += data.len() as u64;
        if topic == super::schema::CHECKPOINT.topic {
            self.checkpoints += 1;
            self.last_checkpoint = Some(step);
        }
        Ok(())
    }

    /// Finish, fsync and rename to the final name; returns the final path.
    pub fn finish(mut self) -> Result<PathBuf> {
        self.writer.finish().map_err(|e| self.witness.mcap_error(&self.tmp, e))?;
        let file = self.writer.into_inner().into_inner().map_err(|e| Error::io(&self.tmp, e.into_error()))?.into_inner().into_inner();
        file.sync_all().map_err(|e| Error::io(&self.tmp, e))?;
        drop(file);
        super::fault::crash_point("segment-synced");
        let last = self.last_checkpoint.unwrap_or(self.first_step);
        let path = self.dir.join(final_name(self.first_step, last));
        if path.exists() {
            return Err(Error::Other(format!("{} already exists; refusing to overwrite a finished segment", path.display())));
        }
        fs::rename(&self.tmp, &path).map_err(|e| Error::io(&path, e))?;
        super::fault::crash_point("segment-renamed");
        sync_dir(&self.dir)?;
        Ok(path)
    }
}

/// The run description (run.json) a finished segment was written with, read through its
/// summary without decompressing a chunk; None when the file has no usable summary (a
/// damaged file, which a whole read reports).
pub fn embedded_run_json(path: &Path) -> Option<String> {
    let file = File::open(path).ok()?;
    // SAFETY: finished segments are never modified (written under a temporary name, renamed).
    let map = unsafe { memmap2::Mmap::map(&file) }.ok()?;
    let summary = mcap::Summary::read(&map).ok()??;
    let index = summary.metadata_indexes.iter().find(|m| m.name == RUN_METADATA)?;
    mcap::read::metadata(&map, index).ok()?.metadata.get("run.json").cloned()
}

pub fn sync_dir(dir: &Path) -> Result<()> {
    File::open(dir).and_then(|d| d.sync_all()).map_err(|e| Error::io(dir, e))
}

/// A message read back from a segment. The run description (the `clv.run` metadata record)
/// is delivered first as a message of topic [`RUN_METADATA`] whose data is its key-value map
/// as a JSON object.
pub struct Message<'a> {
    pub topic: &'a str,
    pub step: u64,
    pub data: &'a [u8],
}

/// What a read found besides the messages.
#[derive(Debug, Default)]
pub struct ReadReport {
    /// The run description embedded in the file.
    pub run_json: Option<String>,
    /// Messages delivered.
    pub messages: u64,
    /// The damage found, if any (the messages before it were delivered).
    pub damage: Option<String>,
}

/// How strictly a file or stream is read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadMode {
    /// Everything checked (end magic, chunk, data-section and summary CRCs); any damage is
    /// an error naming the file.
    Strict,
    /// Everything checked, but damage ends the read and is returned in the report, after
    /// the messages before it were delivered (for analysing what a damaged stream holds).
    Checked,
    /// A file cut short by a crash: read up to its last complete chunk, no end required.
    Salvage,
}

/// Read every message of a segment in file order, checked according to `mode`. Errors
/// from `visit` stop the read and are returned as they are.
pub fn read_segment(path: &Path, mode: ReadMode, visit: impl FnMut(Message) -> Result<()>) -> Result<ReadReport> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map(|m| m.len()).unwrap_or(u64::MAX);
    read_stream_limited(path, std::io::BufReader::with_capacity(1 << 20, file), mode, record_limit(len), visit)
}

/// Largest record accepted from a stream of unknown length (a record length field beyond
/// it is damage, not a reason to allocate).
const STREAM_RECORD_LIMIT: u64 = 1 << 32;

/// Largest record, and largest decompressed chunk, accepted from a file of `len` bytes: a
/// chunk may decompress to more than the file holds (our chunks are a few MB, or one frame,
/// and floating-point data compresses little), so the bound is generous, but a damaged length
/// field can no longer ask for more memory than that.
pub fn record_limit(len: u64) -> u64 {
    len.saturating_mul(64).clamp(256 << 20, STREAM_RECORD_LIMIT)
}

/// [`read_segment`] over any byte stream (a file, or standard input); `name` is used in errors.
pub fn read_stream(name: &Path, input: impl Read, mode: ReadMode, visit: impl FnMut(Message) -> Result<()>) -> Result<ReadReport> {
    read_stream_limited(name, input, mode, STREAM_RECORD_LIMIT, visit)
}

/// The bytes every MCAP file begins (and ends) with.
const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// [`read_stream`] refusing records (and decompressed chunks) longer than `max_record` bytes.
fn read_stream_limited(name: &Path, mut input: impl Read, mode: ReadMode, max_record: u64, mut visit: impl FnMut(Message) -> Result<()>) -> Result<ReadReport> {
    let partial = mode == ReadMode::Salvage;
    let options = LinearReaderOptions::default()
        .with_skip_end_magic(partial)
        // A chunk is checked whole before any of its messages is handed on: a damaged chunk
        // must not feed an analysis some of its messages first.
        .with_prevalidate_chunk_crcs(true)
        .with_validate_data_section_crc(!partial)
        .with_validate_summary_section_crc(!partial)
        .with_record_length_limit(max_record.min(STREAM_RECORD_LIMIT) as usize);
    let mut reader = LinearReader::new_with_options(options);
    let mut report = ReadReport::default();
    let mut topics: BTreeMap<u16, String> = BTreeMap::new();
    let mut consumed = 0u64;
    // The first bytes, to tell a file that is not MCAP at all from a damaged one.
    let mut head = Vec::with_capacity(MAGIC.len());
    while let Some(event) = reader.next_event() {
        let record = match event {
            Ok(LinearReadEvent::ReadRequest(need)) => {
                let buf = reader.insert(need);
                let n = loop {
                    match input.read(buf) {
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        other => break other.map_err(|e| Error::io(name, e))?,
                    }
                };
                let missing = MAGIC.len() - head.len();
                head.extend_from_slice(&buf[..n.min(missing)]);
                consumed += n as u64;
                reader.notify_read(n);
                continue;
            }
            Ok(LinearReadEvent::Record { opcode, data }) => mcap::parse_record(opcode, data),
            Err(e) => Err(e),
        };
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                report.damage = Some(if consumed == 0 {
                    "it is empty: nothing was written to it; from a pipe, the command writing it failed or wrote elsewhere, and its own error says why".to_string()
                } else if !MAGIC.starts_with(&head) {
                    "it is not MCAP at all (it does not begin with the MCAP magic bytes), so neither a frame stream nor a run segment written by clv".to_string()
                } else {
                    format!("{e} (within the first {consumed} bytes, after {} complete messages)", report.messages)
                });
                break;
            }
        };
        match record {
            Record::Metadata(m) if m.name == RUN_METADATA => {
                report.run_json = m.metadata.get("run.json").cloned();
                let map = serde_json::to_vec(&m.metadata).map_err(|e| Error::Other(e.to_string()))?;
                visit(Message { topic: RUN_METADATA, step: 0, data: &map })?;
            }
            Record::Channel(c) => {
                topics.insert(c.id, c.topic.to_string());
            }
            Record::Message { header, data } => {
                let topic = topics.get(&header.channel_id).ok_or_else(|| {
                    Error::corrupt(name, format!("message {} on unknown channel {}", header.sequence, header.channel_id))
                })?;
                visit(Message { topic, step: header.log_time, data: &data })?;
                report.messages += 1;
            }
            _ => {}
        }
    }
    // Bytes after the footer: another stream appended (`cat a b | clv analyze -`) or other
    // output mixed in, which would otherwise go unread without a word.
    if report.damage.is_none() {
        let mut extra = [0u8; 1];
        let n = loop {
            match input.read(&mut extra) {
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                other => break other.map_err(|e| Error::io(name, e))?,
            }
        };
        if n > 0 {
            report.damage = Some(format!(
                "it goes on after its end (the MCAP footer ends at byte {consumed}): another stream or other data follows, which was not read; give one stream at a time"
            ));
        }
    }
    if let (Some(d), ReadMode::Strict) = (&report.damage, mode) {
        return Err(Error::corrupt(name, d.clone()));
    }
    if mode == ReadMode::Strict && report.run_json.is_none() {
        return Err(Error::corrupt(name, "no clv.run metadata record: not a clv segment"));
    }
    Ok(report)
}
