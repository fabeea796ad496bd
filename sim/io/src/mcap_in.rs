//! Reading a recording `hetsim run --record` wrote (ROS 2 MCAP), in file order, without
//! holding it in memory: one top-level record (a chunk, about a megabyte) at a time is read
//! and decompressed.
//!
//! Every failure names the file and where in it: the byte offset of the top-level record, and
//! for a message in a chunk the chunk's offset and the message's index. The whole file's
//! framing is checked when it is opened, so a truncated recording is refused before replay
//! starts; a flipped byte inside a chunk is caught by the chunk's CRC when replay reaches it.
//!
//! Why the framing is read here and not by the `mcap` crate's streaming reader
//! (`mcap::sans_io::LinearReader`, 0.26): that reader checks the same CRCs and limits, but
//! its errors do not say where in the file they are (it exposes no position), and it meets a
//! truncated file only at its end, after replaying everything before. A researcher handed a
//! damaged 14 GB recording needs the byte and the record (the refusals above; the replay
//! tests check them), and a refusal before the run starts. The records themselves are parsed
//! by the crate (`mcap::parse_record`); what is ours is finding them (9-byte headers), the
//! chunk's decompression with its size limit, and the CRCs, about 150 lines.

use crate::cdr_in::{self, Decoded};
use crate::record::{OUTCOME_METADATA, RUN_METADATA};
use hetsim_engine::replay::{Logged, Recording, ReplayError, RunDescription};
use hetsim_engine::RecordedOutcome;
use mcap::records::Record;
use std::collections::{BTreeMap, HashMap};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// Largest chunk hetsim decompresses (a corrupt header could ask for any size).
const MAX_CHUNK_BYTES: u64 = 1 << 30;

impl Recording for McapRecording {
    fn next_logged(&mut self) -> Result<Option<Logged>, ReplayError> {
        McapRecording::next_logged(self)
    }
    fn outcome(&self) -> Option<&[RecordedOutcome]> {
        self.outcome.as_ref().map(|(_, r)| r.as_slice())
    }
    fn ticks(&self) -> Option<u64> {
        self.outcome.as_ref().map(|(t, _)| *t)
    }
    fn has_commands(&self) -> bool {
        true
    }
    fn rendered(&self) -> bool {
        self.run.rendered
    }
}

/// A recording, open for reading.
pub struct McapRecording {
    file: std::fs::File,
    len: u64,
    path: PathBuf,
    /// The run it recorded.
    pub run: RunDescription,
    /// What the physics measured, if the run finished (`hetsim.outcome`).
    pub outcome: Option<(u64, Vec<RecordedOutcome>)>,
    /// Next top-level record.
    at: u64,
    /// The chunk being read: its offset, its records and the read position in them.
    chunk: Option<(u64, Vec<u8>, usize)>,
    schemas: HashMap<u16, (String, String)>,
    channels: HashMap<u16, cdr_in::Channel>,
    messages: u64,
    data_end: u64,
    /// The last message's log time: log times never decrease.
    last_log_ns: u64,
    /// The data section's CRC as the data-end record states it (0: not computed), and the
    /// CRC of every byte read so far: a flipped byte outside a chunk (the header, the
    /// metadata, a schema or channel) is caught at the end of the data, before any output.
    data_crc: u32,
    crc: crc32fast::Hasher,
}

/// Why the framing of a recording's records does not hold.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// A record's header runs past the end of the data or the file.
    #[error("a record starts at byte {at} but the {what} ends at byte {end} (truncated?)")]
    Truncated {
        /// Where the record starts.
        at: u64,
        /// "data" (a chunk's records) or "file".
        what: &'static str,
        /// Where that ends.
        end: u64,
    },
    /// A record's length runs past the end of the data or the file.
    #[error("the record at byte {at} (opcode {op:#04x}) claims {len} bytes, but the {what} ends at byte {end} (truncated?)")]
    Overrun {
        /// Where the record starts.
        at: u64,
        /// Its opcode.
        op: u8,
        /// The length it claims.
        len: u64,
        /// "data" or "file".
        what: &'static str,
        /// Where that ends.
        end: u64,
    },
    /// A record larger than hetsim reads at once.
    #[error("the record at byte {at} claims {len} bytes, more than the {MAX_CHUNK_BYTES} hetsim reads at once (corrupt?)")]
    TooLarge {
        /// Where the record starts.
        at: u64,
        /// The length it claims.
        len: u64,
    },
    /// The file could not be read there.
    #[error("reading byte {at}: {source}")]
    Read {
        /// Where.
        at: u64,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// Why a recording's `hetsim.run` metadata does not describe a run.
#[derive(Debug, thiserror::Error)]
pub enum MetadataError {
    /// No such record.
    #[error("no \"{RUN_METADATA}\" metadata record")]
    Missing,
    /// A key the run needs is absent.
    #[error("the \"{RUN_METADATA}\" metadata has no \"{0}\"")]
    NoKey(String),
    /// A value that is not the number it must be.
    #[error("\"{RUN_METADATA}\" metadata \"{key}\": {why}")]
    NotANumber {
        /// The key.
        key: String,
        /// The parser's word.
        why: String,
    },
}

/// One framed record in a buffer: opcode, body, and the offset after it.
fn frame(buf: &[u8], at: usize) -> Result<(u8, &[u8], usize), FrameError> {
    if buf.len() < at + 9 {
        return Err(FrameError::Truncated {
            at: at as u64,
            what: "data",
            end: buf.len() as u64,
        });
    }
    let op = buf[at];
    let len = u64::from_le_bytes(buf[at + 1..at + 9].try_into().expect("8 bytes"));
    let end = (at as u64 + 9)
        .checked_add(len)
        .filter(|e| *e <= buf.len() as u64);
    let Some(end) = end else {
        return Err(FrameError::Overrun {
            at: at as u64,
            op,
            len,
            what: "data",
            end: buf.len() as u64,
        });
    };
    Ok((op, &buf[at + 9..end as usize], end as usize))
}

/// The opcode and body length of the top-level record at `at`, checked against the file's
/// length.
fn header_at(file: &std::fs::File, len: u64, at: u64) -> Result<(u8, u64), FrameError> {
    let mut head = [0u8; 9];
    if at + 9 > len {
        return Err(FrameError::Truncated {
            at,
            what: "file",
            end: len,
        });
    }
    file.read_exact_at(&mut head, at)
        .map_err(|source| FrameError::Read { at, source })?;
    let body = u64::from_le_bytes(head[1..9].try_into().expect("8 bytes"));
    if (at + 9).checked_add(body).is_none_or(|end| end > len) {
        return Err(FrameError::Overrun {
            at,
            op: head[0],
            len: body,
            what: "file",
            end: len,
        });
    }
    Ok((head[0], body))
}

/// The body of the record at `at` whose length is `body`.
fn body_at(file: &std::fs::File, at: u64, body: u64) -> Result<Vec<u8>, FrameError> {
    if body > MAX_CHUNK_BYTES {
        return Err(FrameError::TooLarge { at, len: body });
    }
    let mut buf = vec![0u8; body as usize];
    file.read_exact_at(&mut buf, at + 9)
        .map_err(|source| FrameError::Read { at: at + 9, source })?;
    Ok(buf)
}

impl McapRecording {
    /// Opens a recording: checks its magic and framing end to end, and reads its run
    /// description.
    pub fn open(path: &Path) -> Result<Self, ReplayError> {
        let file = std::fs::File::open(path).map_err(|e| ReplayError::file(path, e))?;
        let len = file
            .metadata()
            .map_err(|e| ReplayError::file(path, e))?
            .len();
        let bad = |offset: u64, what: String| ReplayError::Corrupt {
            path: path.to_path_buf(),
            offset,
            what,
        };
        let magic_len = mcap::MAGIC.len() as u64;
        let mut magic = [0u8; 8];
        if len < magic_len
            || file.read_exact_at(&mut magic, 0).is_err()
            || magic[..] != *mcap::MAGIC
        {
            return Err(bad(
                0,
                "not an MCAP file (its first 8 bytes are not MCAP's magic)".into(),
            ));
        }
        // The framing, start to end; metadata records are read on the way.
        let mut at = magic_len;
        let mut metadata = BTreeMap::new();
        let mut data_end = None;
        let mut data_crc = 0;
        let mut footer = false;
        while at < len {
            let (op, body) = header_at(&file, len, at).map_err(|w| bad(at, w.to_string()))?;
            match op {
                mcap::records::op::METADATA => {
                    let bytes = body_at(&file, at, body).map_err(|w| bad(at, w.to_string()))?;
                    if let Record::Metadata(m) =
                        mcap::parse_record(op, &bytes).map_err(|e| bad(at, e.to_string()))?
                    {
                        metadata.insert(m.name, m.metadata);
                    }
                }
                mcap::records::op::DATA_END if data_end.is_none() => {
                    let bytes = body_at(&file, at, body).map_err(|w| bad(at, w.to_string()))?;
                    if let Record::DataEnd(d) =
                        mcap::parse_record(op, &bytes).map_err(|e| bad(at, e.to_string()))?
                    {
                        data_crc = d.data_section_crc;
                    }
                    data_end = Some(at);
                }
                mcap::records::op::FOOTER => {
                    let end = at + 9 + body;
                    let mut tail = [0u8; 8];
                    if end + magic_len != len
                        || file.read_exact_at(&mut tail, end).is_err()
                        || tail[..] != *mcap::MAGIC
                    {
                        return Err(bad(
                            end,
                            "no MCAP magic right after the footer (truncated?)".into(),
                        ));
                    }
                    footer = true;
                    break;
                }
                _ => {}
            }
            at += 9 + body;
        }
        let data_end = match (data_end, footer) {
            (Some(d), true) => d,
            _ => {
                return Err(bad(
                    len,
                    "the file ends without its data-end record and footer (truncated: was the run that recorded it stopped?)".into(),
                ))
            }
        };
        let run = run_description(metadata.get(RUN_METADATA))
            .map_err(|w| bad(0, format!("{w}: not a recording hetsim run --record wrote")))?;
        let outcome = metadata
            .get(OUTCOME_METADATA)
            .map(crate::record::Recorder::read_outcome)
            .transpose()
            .map_err(|w| bad(0, format!("the \"{OUTCOME_METADATA}\" metadata: {w}")))?;
        Ok(Self {
            file,
            len,
            path: path.to_path_buf(),
            run,
            outcome,
            at: magic_len,
            chunk: None,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            messages: 0,
            data_end,
            last_log_ns: 0,
            data_crc,
            crc: {
                let mut crc = crc32fast::Hasher::new();
                crc.update(&magic);
                crc
            },
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn corrupt(&self, offset: u64, what: String) -> ReplayError {
        ReplayError::Corrupt {
            path: self.path.clone(),
            offset,
            what,
        }
    }

    /// The next message hetsim replays (truth, command or a robot's sensor message), in
    /// file order; `None` at the end of the data.
    pub fn next_logged(&mut self) -> Result<Option<Logged>, ReplayError> {
        loop {
            // Records of the chunk being read first.
            if let Some((offset, buf, pos)) = self.chunk.take() {
                if pos < buf.len() {
                    let (op, body, next) = frame(&buf, pos).map_err(|w| {
                        self.corrupt(offset, format!("in the chunk at byte {offset}: {w}"))
                    })?;
                    let record = mcap::parse_record(op, body).map_err(|e| {
                        self.corrupt(offset, format!("in the chunk at byte {offset}: {e}"))
                    })?;
                    let record = record.into_owned();
                    self.chunk = Some((offset, buf, next));
                    if let Some(l) = self.record(record, offset)? {
                        return Ok(Some(l));
                    }
                }
                continue;
            }
            if self.at >= self.data_end {
                if self.at == self.data_end && self.data_crc != 0 {
                    let crc = self.crc.clone().finalize();
                    if crc != self.data_crc {
                        return Err(self.corrupt(
                            0,
                            format!(
                                "the data section's CRC is {crc:08x}, its data-end record says {:08x} (flipped bytes outside the chunks: the header, the metadata, a schema or channel?)",
                                self.data_crc
                            ),
                        ));
                    }
                    // Checked once.
                    self.at = self.data_end + 1;
                }
                return Ok(None);
            }
            let at = self.at;
            let (op, len) =
                header_at(&self.file, self.len, at).map_err(|w| self.corrupt(at, w.to_string()))?;
            self.at = at + 9 + len;
            // Every record's bytes go into the data section's CRC, read or skipped.
            let body = body_at(&self.file, at, len).map_err(|w| self.corrupt(at, w.to_string()))?;
            self.crc.update(&[op]);
            self.crc.update(&len.to_le_bytes());
            self.crc.update(&body);
            if !matches!(
                op,
                mcap::records::op::CHUNK
                    | mcap::records::op::SCHEMA
                    | mcap::records::op::CHANNEL
                    | mcap::records::op::MESSAGE
            ) {
                continue;
            }
            if op == mcap::records::op::CHUNK {
                let record =
                    mcap::parse_record(op, &body).map_err(|e| self.corrupt(at, e.to_string()))?;
                let Record::Chunk { header, data } = record else {
                    return Err(self.corrupt(at, "a chunk record that does not parse".into()));
                };
                let buf = self.decompress(at, &header, &data)?;
                self.chunk = Some((at, buf, 0));
                continue;
            }
            let record = mcap::parse_record(op, &body)
                .map_err(|e| self.corrupt(at, e.to_string()))?
                .into_owned();
            if let Some(l) = self.record(record, at)? {
                return Ok(Some(l));
            }
        }
    }

    fn decompress(
        &self,
        at: u64,
        header: &mcap::records::ChunkHeader,
        data: &[u8],
    ) -> Result<Vec<u8>, ReplayError> {
        if header.uncompressed_size > MAX_CHUNK_BYTES {
            return Err(self.corrupt(
                at,
                format!(
                    "the chunk claims {} bytes uncompressed, more than the {MAX_CHUNK_BYTES} hetsim reads (corrupt?)",
                    header.uncompressed_size
                ),
            ));
        }
        let buf = match header.compression.as_str() {
            "" => data.to_vec(),
            "zstd" => {
                zstd::bulk::decompress(data, header.uncompressed_size as usize).map_err(|e| {
                    self.corrupt(
                        at,
                        format!("the chunk's zstd data does not decompress: {e}"),
                    )
                })?
            }
            other => {
                return Err(self.corrupt(
                    at,
                    format!(
                        "chunk compression \"{other}\": hetsim reads zstd or uncompressed chunks"
                    ),
                ))
            }
        };
        if buf.len() as u64 != header.uncompressed_size {
            return Err(self.corrupt(
                at,
                format!(
                    "the chunk decompresses to {} bytes, its header says {}",
                    buf.len(),
                    header.uncompressed_size
                ),
            ));
        }
        let crc = crc32fast::hash(&buf);
        if header.uncompressed_crc != 0 && crc != header.uncompressed_crc {
            return Err(self.corrupt(
                at,
                format!(
                    "the chunk's CRC is {crc:08x}, its header says {:08x} (flipped bytes?)",
                    header.uncompressed_crc
                ),
            ));
        }
        Ok(buf)
    }

    /// Registers a schema or channel, or decodes a message.
    fn record(&mut self, record: Record<'static>, at: u64) -> Result<Option<Logged>, ReplayError> {
        match record {
            Record::Schema { header, .. } => {
                self.schemas
                    .insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(c) => {
                let (schema, encoding) =
                    self.schemas.get(&c.schema_id).cloned().ok_or_else(|| {
                        self.corrupt(
                            at,
                            format!(
                                "channel {} names schema {}, which is not defined before it",
                                c.topic, c.schema_id
                            ),
                        )
                    })?;
                let channel =
                    cdr_in::Channel::of(&c.topic, &schema, &encoding, &c.message_encoding)
                        .map_err(|w| self.corrupt(at, format!("channel {}: {w}", c.topic)))?;
                self.channels.insert(c.id, channel);
            }
            Record::Message { header, data } => {
                self.messages += 1;
                let index = self.messages;
                let channel = self.channels.get(&header.channel_id).ok_or_else(|| {
                    self.corrupt(
                        at,
                        format!(
                            "message {index} is on channel {}, which is not defined before it",
                            header.channel_id
                        ),
                    )
                })?;
                let decoded = channel.decode(&data).map_err(|w| {
                    self.corrupt(
                        at,
                        format!(
                            "message {index} on {} (log time {} ns): {w}",
                            channel.topic, header.log_time
                        ),
                    )
                })?;
                let Decoded::Event(event) = decoded else {
                    return Ok(None);
                };
                // Delivery times on the tick grid, never decreasing, never before the stamp:
                // anything else would feed the robots at the wrong ticks.
                let log = header.log_time;
                let stamp = event.stamp_ns();
                let dt = self.run.dt_ns.max(1);
                let wrong = if log % dt != 0 {
                    Some(format!("is not on the {dt} ns tick grid"))
                } else if log < self.last_log_ns {
                    Some(format!(
                        "is before the previous message's ({} ns)",
                        self.last_log_ns
                    ))
                } else if log < stamp {
                    Some(format!("is before the message's own stamp ({stamp} ns)"))
                } else {
                    None
                };
                if let Some(w) = wrong {
                    let topic = &self.channels[&header.channel_id].topic;
                    return Err(self.corrupt(
                        at,
                        format!("message {index} on {topic}: its log time {log} ns {w}"),
                    ));
                }
                self.last_log_ns = log;
                return Ok(Some(Logged { log_ns: log, event }));
            }
            _ => {}
        }
        Ok(None)
    }
}

/// The run a recording describes, from its `hetsim.run` metadata record.
fn run_description(m: Option<&BTreeMap<String, String>>) -> Result<RunDescription, MetadataError> {
    let m = m.ok_or(MetadataError::Missing)?;
    let get = |k: &str| m.get(k).ok_or_else(|| MetadataError::NoKey(k.to_string()));
    let bad = |k: &str, e: &dyn std::fmt::Display| MetadataError::NotANumber {
        key: k.to_string(),
        why: e.to_string(),
    };
    let number =
        |k: &str| -> Result<f64, MetadataError> { get(k)?.parse::<f64>().map_err(|e| bad(k, &e)) };
    Ok(RunDescription {
        dt_ns: get("dt_ns")?.parse().map_err(|e| bad("dt_ns", &e))?,
        open_loop: get("open_loop")? == "true",
        rendered: get("rendered")? == "true",
        camera_profile: match m.get("camera_profile").map(String::as_str) {
            None => None,
            Some("perfect") => Some(hetsim_scene::CameraProfile::Perfect),
            Some("realistic") => Some(hetsim_scene::CameraProfile::Realistic),
            Some(other) => {
                return Err(MetadataError::NotANumber {
                    key: "camera_profile".into(),
                    why: format!("{other:?} is neither \"realistic\" nor \"perfect\""),
                })
            }
        },
        scenario_path: PathBuf::from(get("scenario_path")?),
        scenario_text: get("scenario")?.clone(),
        seed: get("seed")?.parse().map_err(|e| bad("seed", &e))?,
        duration_secs: number("duration_secs")?,
        robot_files: m
            .iter()
            .filter_map(|(k, v)| Some((k.strip_prefix("robot_file/")?.to_string(), v.clone())))
            .collect(),
    })
}
