//! A streaming MCAP reader of our own: records are read one at a time from a file, a chunk
//! is decompressed into one reused buffer (zstd with `ruzstd`, lz4 frames with `lz4_flex`,
//! both pure Rust) and its messages are handed out as slices of that buffer.
//!
//! Why not the `mcap` crate: its zstd and lz4 support builds C, and without them a
//! compressed chunk cannot be read; its reader also wants the whole file in memory. This
//! reader needs neither: memory is one record (a chunk, compressed) plus that chunk
//! decompressed, whatever the file's size.
//!
//! Only what tracking needs is parsed: the header, schemas, channels, messages, chunks,
//! the data-end record and the footer (with the summary's schemas, channels and statistics
//! when the file has a summary). Every other record is skipped by seeking. Every length is
//! checked against the bytes that remain, so a corrupted length is an error, never a huge
//! allocation.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// The 8 bytes that open and close every MCAP file.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// The largest record or decompressed chunk accepted, bytes: [`crate::limits::max_buffer`]
/// (a quarter of `--max-memory`, at most 1 GiB). A declared length beyond it is an error
/// before anything is allocated, and a chunk is never decompressed past its declared size.
pub fn max_record() -> u64 {
    crate::limits::max_buffer()
}

pub(crate) mod op {
    pub const HEADER: u8 = 0x01;
    pub const FOOTER: u8 = 0x02;
    pub const SCHEMA: u8 = 0x03;
    pub const CHANNEL: u8 = 0x04;
    pub const MESSAGE: u8 = 0x05;
    pub const CHUNK: u8 = 0x06;
    pub const MESSAGE_INDEX: u8 = 0x07;
    pub const CHUNK_INDEX: u8 = 0x08;
    pub const STATISTICS: u8 = 0x0B;
    pub const SUMMARY_OFFSET: u8 = 0x0E;
    pub const DATA_END: u8 = 0x0F;
}

/// Errors of the MCAP reader: the file, and where in it.
#[derive(Debug, thiserror::Error)]
pub enum McapError {
    /// The file cannot be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file does not start with the MCAP magic.
    #[error("{path} is not an MCAP file (it does not start with the MCAP magic bytes)")]
    NotMcap {
        /// The file.
        path: PathBuf,
    },
    /// The file ends inside a record.
    #[error("{path} is truncated: it ends inside a record at byte {offset}")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Where the incomplete record starts.
        offset: u64,
    },
    /// A record's content is not what the MCAP specification says.
    #[error("{path}: malformed {what} record at byte {offset}: {reason}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// The record kind.
        what: &'static str,
        /// Where it starts.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// A chunk's CRC does not match its content.
    #[error(
        "{path}: chunk at byte {offset} is corrupt (CRC {found:08x}, the chunk says {expected:08x})"
    )]
    Crc {
        /// The file.
        path: PathBuf,
        /// Where the chunk starts.
        offset: u64,
        /// The CRC the chunk records.
        expected: u32,
        /// The CRC of what was read.
        found: u32,
    },
    /// A chunk is compressed with something we do not decode.
    #[error(
        "{path}: chunk at byte {offset} uses compression `{compression}` (supported: none, zstd, lz4)"
    )]
    Compression {
        /// The file.
        path: PathBuf,
        /// Where the chunk starts.
        offset: u64,
        /// The compression named.
        compression: String,
    },
}

/// A schema record: the message type's name and definition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Schema {
    /// Id, unique in its file.
    pub id: u16,
    /// Message type, e.g. `sensor_msgs/msg/Image`.
    pub name: String,
    /// Schema encoding, e.g. `ros2msg`.
    pub encoding: String,
}

/// A channel record: a topic and how its messages are encoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Channel {
    /// Id, unique in its file.
    pub id: u16,
    /// The schema's id (0: none).
    pub schema_id: u16,
    /// Topic name.
    pub topic: String,
    /// Message encoding, e.g. `cdr`.
    pub message_encoding: String,
}

/// One message, borrowing the reader's buffer.
#[derive(Debug, Clone, Copy)]
pub struct MessageRef<'a> {
    /// Its channel's id.
    pub channel_id: u16,
    /// Log time, nanoseconds.
    pub log_time: u64,
    /// The serialized message.
    pub data: &'a [u8],
}

/// Little-endian field reader over a record body, with every read bounds-checked.
#[derive(Debug)]
pub(crate) struct Fields<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Fields<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }
    pub(crate) fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|e| *e <= self.bytes.len())
            .ok_or_else(|| {
                format!(
                    "field of {n} bytes at {} runs past the record's {} bytes",
                    self.pos,
                    self.bytes.len()
                )
            })?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    pub(crate) fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    pub(crate) fn u16(&mut self) -> Result<u16, String> {
        let b = self.take(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    pub(crate) fn u32(&mut self) -> Result<u32, String> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    pub(crate) fn u64(&mut self) -> Result<u64, String> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
    pub(crate) fn string(&mut self) -> Result<String, String> {
        let n = self.u32()? as usize;
        let b = self.take(n)?;
        String::from_utf8(b.to_vec()).map_err(|_| "a string is not UTF-8".to_owned())
    }
    /// Bytes with a u32 length prefix.
    pub(crate) fn bytes32(&mut self) -> Result<&'a [u8], String> {
        let n = self.u32()? as usize;
        self.take(n)
    }
    /// Bytes with a u64 length prefix.
    pub(crate) fn bytes64(&mut self) -> Result<&'a [u8], String> {
        let n = usize::try_from(self.u64()?).map_err(|_| "length too large".to_owned())?;
        self.take(n)
    }
    pub(crate) fn rest(&mut self) -> &'a [u8] {
        let s = &self.bytes[self.pos..];
        self.pos = self.bytes.len();
        s
    }
}

/// What the summary section says (when the file has one).
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// Schemas by id.
    pub schemas: BTreeMap<u16, Schema>,
    /// Channels by id.
    pub channels: BTreeMap<u16, Channel>,
    /// Messages per channel id, from the statistics record.
    pub message_counts: BTreeMap<u16, u64>,
}

/// Where the reader is: in the file's records, or inside a decompressed chunk.
#[derive(Debug)]
enum Cursor {
    Records,
    /// The chunk's records are `chunk[pos..end]`.
    Chunk {
        pos: usize,
        end: usize,
    },
}

/// A streaming reader of one MCAP file.
#[derive(Debug)]
pub struct McapReader {
    path: PathBuf,
    file: BufReader<File>,
    len: u64,
    offset: u64,
    body: Vec<u8>,
    chunk: Vec<u8>,
    cursor: Cursor,
    /// Message record inside `chunk` or `body` to hand out: (start, end) of its body.
    message: Option<(bool, usize, usize)>,
    schemas: BTreeMap<u16, Schema>,
    channels: BTreeMap<u16, Channel>,
    done: bool,
}

impl McapReader {
    /// Opens `path` and checks its magic.
    ///
    /// # Errors
    /// The file cannot be read or is not MCAP.
    pub fn open(path: &Path) -> Result<Self, McapError> {
        let io = |source| McapError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        let mut file = BufReader::with_capacity(1 << 16, file);
        let mut magic = [0u8; 8];
        if len < 8 || file.read_exact(&mut magic).is_err() || &magic != MAGIC {
            return Err(McapError::NotMcap {
                path: path.to_path_buf(),
            });
        }
        Ok(Self {
            path: path.to_path_buf(),
            file,
            len,
            offset: 8,
            body: Vec::new(),
            chunk: Vec::new(),
            cursor: Cursor::Records,
            message: None,
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            done: false,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Schemas seen so far.
    pub fn schemas(&self) -> &BTreeMap<u16, Schema> {
        &self.schemas
    }

    /// Channels seen so far.
    pub fn channels(&self) -> &BTreeMap<u16, Channel> {
        &self.channels
    }

    /// Bytes of the file read so far.
    pub fn position(&self) -> u64 {
        self.offset
    }

    /// The file's size, bytes.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether the file is empty (never, for an opened MCAP file).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn io(&self, source: std::io::Error) -> McapError {
        McapError::Io {
            path: self.path.clone(),
            source,
        }
    }

    fn malformed(&self, what: &'static str, offset: u64, reason: String) -> McapError {
        McapError::Malformed {
            path: self.path.clone(),
            what,
            offset,
            reason,
        }
    }

    /// Reads the summary section through the footer, without moving the stream.
    ///
    /// # Errors
    /// An unreadable or malformed footer or summary. `Ok(None)`: the file has no summary (or
    /// no footer, e.g. a recording that was cut off).
    pub fn summary(&self) -> Result<Option<Summary>, McapError> {
        let footer_len = 1 + 8 + 20 + 8;
        if self.len < 8 + footer_len {
            return Ok(None);
        }
        let mut file = File::open(&self.path).map_err(|e| self.io(e))?;
        let start = self.len - footer_len;
        file.seek(SeekFrom::Start(start)).map_err(|e| self.io(e))?;
        let mut tail = [0u8; 37];
        file.read_exact(&mut tail).map_err(|e| self.io(e))?;
        if &tail[29..] != MAGIC || tail[0] != op::FOOTER {
            return Ok(None);
        }
        let mut f = Fields::new(&tail[9..29]);
        let bad = |r: String| self.malformed("footer", start, r);
        let summary_start = f.u64().map_err(bad)?;
        if summary_start == 0 {
            return Ok(None);
        }
        if summary_start < 8 || summary_start > start {
            return Err(self.malformed(
                "footer",
                start,
                format!("summary start {summary_start} is outside the file"),
            ));
        }
        let n = usize::try_from(start - summary_start)
            .ok()
            .filter(|n| *n as u64 <= max_record())
            .ok_or_else(|| self.malformed("footer", start, "summary too large".into()))?;
        let mut bytes = vec![0u8; n];
        file.seek(SeekFrom::Start(summary_start))
            .map_err(|e| self.io(e))?;
        file.read_exact(&mut bytes).map_err(|e| self.io(e))?;
        let mut out = Summary::default();
        let mut f = Fields::new(&bytes);
        while f.pos < bytes.len() {
            let at = summary_start + f.pos as u64;
            let bad = |r: String| self.malformed("summary", at, r);
            let opcode = f.u8().map_err(bad)?;
            let body = f.bytes64().map_err(bad)?;
            match opcode {
                op::SCHEMA => {
                    let s = parse_schema(body).map_err(|r| self.malformed("schema", at, r))?;
                    out.schemas.insert(s.id, s);
                }
                op::CHANNEL => {
                    let c = parse_channel(body).map_err(|r| self.malformed("channel", at, r))?;
                    out.channels.insert(c.id, c);
                }
                op::STATISTICS => {
                    out.message_counts =
                        parse_statistics(body).map_err(|r| self.malformed("statistics", at, r))?;
                }
                _ => {}
            }
        }
        Ok(Some(out))
    }

    /// The next message of the file; `Ok(None)` at the end of the data section.
    ///
    /// # Errors
    /// A truncated file, a malformed record, a bad chunk CRC or an unknown compression. The
    /// stream cannot go on after an error (the next call returns `Ok(None)`).
    pub fn next_message(&mut self) -> Result<Option<MessageRef<'_>>, McapError> {
        match self.advance() {
            Ok(true) => {}
            Ok(false) => return Ok(None),
            Err(e) => {
                self.done = true;
                return Err(e);
            }
        }
        let Some((in_chunk, start, end)) = self.message else {
            return Ok(None);
        };
        let buf = if in_chunk { &self.chunk } else { &self.body };
        let mut f = Fields::new(&buf[start..end]);
        // Checked in `advance`.
        let channel_id = f.u16().unwrap_or(0);
        let _sequence = f.u32().unwrap_or(0);
        let log_time = f.u64().unwrap_or(0);
        let _publish_time = f.u64().unwrap_or(0);
        Ok(Some(MessageRef {
            channel_id,
            log_time,
            data: f.rest(),
        }))
    }

    /// The serialized data of the message [`McapReader::next_message`] returned last (empty
    /// if there is none).
    pub fn last_message_data(&self) -> &[u8] {
        match self.message {
            Some((in_chunk, start, end)) => {
                let buf = if in_chunk { &self.chunk } else { &self.body };
                buf.get(start + 22..end).unwrap_or(&[])
            }
            None => &[],
        }
    }

    /// Moves to the next message record; false at the end.
    fn advance(&mut self) -> Result<bool, McapError> {
        self.message = None;
        loop {
            if self.done {
                return Ok(false);
            }
            if let Cursor::Chunk { pos, end } = self.cursor {
                if pos >= end {
                    self.cursor = Cursor::Records;
                    continue;
                }
                let mut f = Fields::new(&self.chunk[pos..end]);
                let at = self.offset;
                let parsed = (|| -> Result<(u8, usize), String> {
                    let opcode = f.u8()?;
                    let body = f.bytes64()?;
                    Ok((opcode, body.len()))
                })();
                let (opcode, n) = parsed.map_err(|r| {
                    self.malformed("chunk", at, format!("inner record at {pos}: {r}"))
                })?;
                let start = pos + 9;
                let record_end = start + n;
                self.cursor = Cursor::Chunk {
                    pos: record_end,
                    end,
                };
                if self.record(opcode, true, start, record_end, at)? {
                    return Ok(true);
                }
                continue;
            }
            // A record of the file.
            let at = self.offset;
            let mut head = [0u8; 9];
            let remaining = self.len - self.offset;
            if remaining < 9 {
                // Also at exactly the end: no data-end record or footer, a recording cut off
                // between records.
                return Err(McapError::Truncated {
                    path: self.path.clone(),
                    offset: at,
                });
            }
            self.file.read_exact(&mut head).map_err(|e| self.io(e))?;
            let opcode = head[0];
            let mut l = [0u8; 8];
            l.copy_from_slice(&head[1..]);
            let n = u64::from_le_bytes(l);
            if n > self.len - self.offset - 9 {
                self.done = true;
                return Err(McapError::Truncated {
                    path: self.path.clone(),
                    offset: at,
                });
            }
            self.offset += 9 + n;
            let wanted = matches!(
                opcode,
                op::HEADER | op::SCHEMA | op::CHANNEL | op::MESSAGE | op::CHUNK
            );
            if !wanted {
                if opcode == op::DATA_END || opcode == op::FOOTER {
                    self.done = true;
                    return Ok(false);
                }
                let skip = i64::try_from(n).map_err(|_| {
                    self.malformed("record", at, format!("length {n} is too large"))
                })?;
                self.file.seek_relative(skip).map_err(|e| self.io(e))?;
                continue;
            }
            let limit = max_record();
            if n > limit {
                return Err(self.malformed(
                    "record",
                    at,
                    format!(
                        "{n} bytes is more than the {limit}-byte limit (a quarter of --max-memory)"
                    ),
                ));
            }
            // Read without zero-filling the buffer first.
            self.body.clear();
            let read = (&mut self.file)
                .take(n)
                .read_to_end(&mut self.body)
                .map_err(|e| McapError::Io {
                    path: self.path.clone(),
                    source: e,
                })?;
            if read as u64 != n {
                return Err(McapError::Truncated {
                    path: self.path.clone(),
                    offset: at,
                });
            }
            if opcode == op::CHUNK {
                let (pos, end) = self.decompress_chunk(at)?;
                self.cursor = Cursor::Chunk { pos, end };
                continue;
            }
            if self.record(opcode, false, 0, n as usize, at)? {
                return Ok(true);
            }
        }
    }

    /// Handles one record whose body is `buf[start..end]`; true for a message.
    fn record(
        &mut self,
        opcode: u8,
        in_chunk: bool,
        start: usize,
        end: usize,
        at: u64,
    ) -> Result<bool, McapError> {
        let buf = if in_chunk { &self.chunk } else { &self.body };
        let body = &buf[start..end];
        match opcode {
            op::SCHEMA => {
                let s = parse_schema(body).map_err(|r| self.malformed("schema", at, r))?;
                self.schemas.insert(s.id, s);
            }
            op::CHANNEL => {
                let c = parse_channel(body).map_err(|r| self.malformed("channel", at, r))?;
                self.channels.insert(c.id, c);
            }
            op::MESSAGE => {
                if body.len() < 22 {
                    return Err(self.malformed(
                        "message",
                        at,
                        format!("{} bytes, shorter than its 22-byte header", body.len()),
                    ));
                }
                self.message = Some((in_chunk, start, end));
                return Ok(true);
            }
            _ => {}
        }
        Ok(false)
    }

    /// Decompresses the chunk whose body is in `self.body` into `self.chunk` (an
    /// uncompressed chunk's body simply becomes `self.chunk`, without a copy); returns where
    /// its records are in `self.chunk`.
    fn decompress_chunk(&mut self, at: u64) -> Result<(usize, usize), McapError> {
        let mut f = Fields::new(&self.body);
        let parsed = (|| -> Result<_, String> {
            let _start = f.u64()?;
            let _end = f.u64()?;
            let size = f.u64()?;
            let crc = f.u32()?;
            let compression = f.string()?;
            let records = f.bytes64()?;
            Ok((size, crc, compression, records))
        })();
        let (size, crc, compression, records) =
            parsed.map_err(|r| self.malformed("chunk", at, r))?;
        let limit = max_record();
        if size > limit {
            return Err(self.malformed(
                "chunk",
                at,
                format!(
                    "uncompressed size {size} bytes is more than the {limit}-byte limit (a quarter of --max-memory)"
                ),
            ));
        }
        let size = size as usize;
        if compression.is_empty() {
            if records.len() != size {
                return Err(self.malformed(
                    "chunk",
                    at,
                    format!("{} bytes of records, the chunk says {size}", records.len()),
                ));
            }
            check_crc(&self.path, at, crc, records)?;
            let start = f.pos - records.len();
            std::mem::swap(&mut self.chunk, &mut self.body);
            return Ok((start, start + size));
        }
        self.chunk.clear();
        match compression.as_str() {
            "zstd" => {
                let mut dec = ruzstd::decoding::StreamingDecoder::new(records)
                    .map_err(|e| self.malformed("chunk", at, format!("zstd: {e}")))?;
                // At most one byte more than promised, to notice a lie.
                (&mut dec)
                    .take(size as u64 + 1)
                    .read_to_end(&mut self.chunk)
                    .map_err(|e| self.malformed("chunk", at, format!("zstd: {e}")))?;
            }
            "lz4" => {
                let mut dec = lz4_flex::frame::FrameDecoder::new(records);
                (&mut dec)
                    .take(size as u64 + 1)
                    .read_to_end(&mut self.chunk)
                    .map_err(|e| self.malformed("chunk", at, format!("lz4: {e}")))?;
            }
            other => {
                return Err(McapError::Compression {
                    path: self.path.clone(),
                    offset: at,
                    compression: other.to_owned(),
                });
            }
        }
        if self.chunk.len() != size {
            return Err(self.malformed(
                "chunk",
                at,
                format!(
                    "decompresses to {} bytes, the chunk says {size}",
                    self.chunk.len()
                ),
            ));
        }
        check_crc(&self.path, at, crc, &self.chunk)?;
        Ok((0, self.chunk.len()))
    }
}

/// A chunk's CRC against its records (0: the writer recorded none).
fn check_crc(path: &Path, at: u64, expected: u32, records: &[u8]) -> Result<(), McapError> {
    if expected == 0 {
        return Ok(());
    }
    let found = crc32fast::hash(records);
    if found == expected {
        Ok(())
    } else {
        Err(McapError::Crc {
            path: path.to_path_buf(),
            offset: at,
            expected,
            found,
        })
    }
}

fn parse_schema(body: &[u8]) -> Result<Schema, String> {
    let mut f = Fields::new(body);
    let id = f.u16()?;
    let name = f.string()?;
    let encoding = f.string()?;
    let _data = f.bytes32()?;
    Ok(Schema { id, name, encoding })
}

fn parse_channel(body: &[u8]) -> Result<Channel, String> {
    let mut f = Fields::new(body);
    let id = f.u16()?;
    let schema_id = f.u16()?;
    let topic = f.string()?;
    let message_encoding = f.string()?;
    Ok(Channel {
        id,
        schema_id,
        topic,
        message_encoding,
    })
}

fn parse_statistics(body: &[u8]) -> Result<BTreeMap<u16, u64>, String> {
    let mut f = Fields::new(body);
    let _messages = f.u64()?;
    let _schemas = f.u16()?;
    let _channels = f.u32()?;
    let _attachments = f.u32()?;
    let _metadata = f.u32()?;
    let _chunks = f.u32()?;
    let _start = f.u64()?;
    let _end = f.u64()?;
    let map = f.bytes32()?;
    let mut m = Fields::new(map);
    let mut out = BTreeMap::new();
    while m.pos < map.len() {
        let id = m.u16()?;
        let n = m.u64()?;
        out.insert(id, n);
    }
    Ok(out)
}
