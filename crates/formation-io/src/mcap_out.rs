//! An MCAP writer: chunked, indexed and summarised, so that Foxglove (and Rerun, or the
//! `mcap` command-line tool) can seek in the file.
//!
//! Chunks are not compressed (the images dominate and compress poorly; readers need no
//! decompressor). Each chunk is followed by its message indexes; the summary section holds
//! every schema and channel, the statistics and the chunk indexes, with a summary-offset
//! record per group, and the footer carries the summary's CRC.

use std::collections::BTreeMap;
use std::io::{self, Write};

use crate::bag::mcap::{MAGIC, op};

/// Messages are gathered into chunks of about this many bytes.
pub const CHUNK_SIZE: usize = 4 << 20;

#[derive(Debug, Clone)]
struct ChunkIndex {
    start: u64,
    end: u64,
    offset: u64,
    length: u64,
    message_index_offsets: Vec<(u16, u64)>,
    message_index_length: u64,
    size: u64,
}

/// A streaming MCAP writer over any `Write`.
#[derive(Debug)]
pub struct McapWriter<W: Write> {
    out: W,
    pos: u64,
    chunk: Vec<u8>,
    chunk_times: Option<(u64, u64)>,
    chunk_messages: BTreeMap<u16, Vec<(u64, u64)>>,
    chunk_indexes: Vec<ChunkIndex>,
    schemas: Vec<Vec<u8>>,
    channels: Vec<Vec<u8>>,
    counts: BTreeMap<u16, u64>,
    times: Option<(u64, u64)>,
    messages: u64,
}

fn put_str(buf: &mut Vec<u8>, s: &str) {
    buf.extend_from_slice(&(s.len() as u32).to_le_bytes());
    buf.extend_from_slice(s.as_bytes());
}

fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
    let mut r = Vec::with_capacity(9 + body.len());
    r.push(opcode);
    r.extend_from_slice(&(body.len() as u64).to_le_bytes());
    r.extend_from_slice(body);
    r
}

impl<W: Write> McapWriter<W> {
    /// Starts a file: magic and header (`profile` e.g. `ros2` or empty).
    ///
    /// # Errors
    /// A failed write.
    pub fn new(mut out: W, profile: &str) -> io::Result<Self> {
        let mut body = Vec::new();
        put_str(&mut body, profile);
        put_str(
            &mut body,
            concat!("formation-tracker ", env!("CARGO_PKG_VERSION")),
        );
        let header = record(op::HEADER, &body);
        out.write_all(MAGIC)?;
        out.write_all(&header)?;
        Ok(Self {
            out,
            pos: (MAGIC.len() + header.len()) as u64,
            chunk: Vec::new(),
            chunk_times: None,
            chunk_messages: BTreeMap::new(),
            chunk_indexes: Vec::new(),
            schemas: Vec::new(),
            channels: Vec::new(),
            counts: BTreeMap::new(),
            times: None,
            messages: 0,
        })
    }

    fn raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.out.write_all(bytes)?;
        self.pos += bytes.len() as u64;
        Ok(())
    }

    /// Adds a schema (`encoding` e.g. `jsonschema`, `ros2msg`); returns its id.
    ///
    /// # Errors
    /// A failed write.
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> io::Result<u16> {
        let id = self.schemas.len() as u16 + 1;
        let mut body = id.to_le_bytes().to_vec();
        put_str(&mut body, name);
        put_str(&mut body, encoding);
        body.extend_from_slice(&(data.len() as u32).to_le_bytes());
        body.extend_from_slice(data);
        let r = record(op::SCHEMA, &body);
        self.flush_chunk()?;
        self.raw(&r)?;
        self.schemas.push(r);
        Ok(id)
    }

    /// Adds a channel on `topic` with `schema_id` (`encoding` e.g. `json`, `cdr`); returns
    /// its id.
    ///
    /// # Errors
    /// A failed write.
    pub fn add_channel(&mut self, schema_id: u16, topic: &str, encoding: &str) -> io::Result<u16> {
        let id = self.channels.len() as u16;
        let mut body = id.to_le_bytes().to_vec();
        body.extend_from_slice(&schema_id.to_le_bytes());
        put_str(&mut body, topic);
        put_str(&mut body, encoding);
        body.extend_from_slice(&0u32.to_le_bytes());
        let r = record(op::CHANNEL, &body);
        self.flush_chunk()?;
        self.raw(&r)?;
        self.channels.push(r);
        self.counts.insert(id, 0);
        Ok(id)
    }

    /// Writes one message (times in nanoseconds).
    ///
    /// # Errors
    /// A failed write.
    pub fn write(&mut self, channel: u16, log_time: u64, data: &[u8]) -> io::Result<()> {
        let sequence = self.counts.get(&channel).copied().unwrap_or(0) as u32;
        let offset = self.chunk.len() as u64;
        self.chunk.push(op::MESSAGE);
        self.chunk
            .extend_from_slice(&(22 + data.len() as u64).to_le_bytes());
        self.chunk.extend_from_slice(&channel.to_le_bytes());
        self.chunk.extend_from_slice(&sequence.to_le_bytes());
        self.chunk.extend_from_slice(&log_time.to_le_bytes());
        self.chunk.extend_from_slice(&log_time.to_le_bytes());
        self.chunk.extend_from_slice(data);
        self.chunk_messages
            .entry(channel)
            .or_default()
            .push((log_time, offset));
        let widen = |t: Option<(u64, u64)>| {
            Some(t.map_or((log_time, log_time), |(a, b)| {
                (a.min(log_time), b.max(log_time))
            }))
        };
        self.chunk_times = widen(self.chunk_times);
        self.times = widen(self.times);
        *self.counts.entry(channel).or_default() += 1;
        self.messages += 1;
        if self.chunk.len() >= CHUNK_SIZE {
            self.flush_chunk()?;
        }
        Ok(())
    }

    fn flush_chunk(&mut self) -> io::Result<()> {
        let Some((start, end)) = self.chunk_times.take() else {
            return Ok(());
        };
        let records = std::mem::take(&mut self.chunk);
        let mut body = Vec::with_capacity(records.len() + 40);
        body.extend_from_slice(&start.to_le_bytes());
        body.extend_from_slice(&end.to_le_bytes());
        body.extend_from_slice(&(records.len() as u64).to_le_bytes());
        body.extend_from_slice(&crc32fast::hash(&records).to_le_bytes());
        put_str(&mut body, "");
        body.extend_from_slice(&(records.len() as u64).to_le_bytes());
        body.extend_from_slice(&records);
        let offset = self.pos;
        let chunk = record(op::CHUNK, &body);
        self.raw(&chunk)?;
        let index_start = self.pos;
        let mut offsets = Vec::new();
        for (channel, entries) in std::mem::take(&mut self.chunk_messages) {
            let mut b = channel.to_le_bytes().to_vec();
            b.extend_from_slice(&((entries.len() * 16) as u32).to_le_bytes());
            for (t, o) in entries {
                b.extend_from_slice(&t.to_le_bytes());
                b.extend_from_slice(&o.to_le_bytes());
            }
            offsets.push((channel, self.pos));
            self.raw(&record(op::MESSAGE_INDEX, &b))?;
        }
        self.chunk_indexes.push(ChunkIndex {
            start,
            end,
            offset,
            length: chunk.len() as u64,
            message_index_offsets: offsets,
            message_index_length: self.pos - index_start,
            size: records.len() as u64,
        });
        Ok(())
    }

    /// Ends the file: the last chunk, the data-end record, the summary and the footer.
    /// Returns the writer.
    ///
    /// # Errors
    /// A failed write.
    pub fn finish(mut self) -> io::Result<W> {
        self.flush_chunk()?;
        self.raw(&record(op::DATA_END, &0u32.to_le_bytes()))?;
        let summary_start = self.pos;
        let mut summary = Vec::new();
        let mut groups: Vec<(u8, u64, u64)> = Vec::new();
        let mut group = |summary: &mut Vec<u8>, opcode: u8, records: &[Vec<u8>]| {
            if records.is_empty() {
                return;
            }
            let start = summary_start + summary.len() as u64;
            for r in records {
                summary.extend_from_slice(r);
            }
            groups.push((opcode, start, summary_start + summary.len() as u64 - start));
        };
        group(&mut summary, op::SCHEMA, &self.schemas);
        group(&mut summary, op::CHANNEL, &self.channels);
        let (t0, t1) = self.times.unwrap_or((0, 0));
        let mut stats = self.messages.to_le_bytes().to_vec();
        stats.extend_from_slice(&(self.schemas.len() as u16).to_le_bytes());
        stats.extend_from_slice(&(self.channels.len() as u32).to_le_bytes());
        stats.extend_from_slice(&0u32.to_le_bytes());
        stats.extend_from_slice(&0u32.to_le_bytes());
        stats.extend_from_slice(&(self.chunk_indexes.len() as u32).to_le_bytes());
        stats.extend_from_slice(&t0.to_le_bytes());
        stats.extend_from_slice(&t1.to_le_bytes());
        stats.extend_from_slice(&((self.counts.len() * 10) as u32).to_le_bytes());
        for (id, n) in &self.counts {
            stats.extend_from_slice(&id.to_le_bytes());
            stats.extend_from_slice(&n.to_le_bytes());
        }
        group(
            &mut summary,
            op::STATISTICS,
            &[record(op::STATISTICS, &stats)],
        );
        let chunk_indexes: Vec<Vec<u8>> = self
            .chunk_indexes
            .iter()
            .map(|c| {
                let mut b = Vec::new();
                b.extend_from_slice(&c.start.to_le_bytes());
                b.extend_from_slice(&c.end.to_le_bytes());
                b.extend_from_slice(&c.offset.to_le_bytes());
                b.extend_from_slice(&c.length.to_le_bytes());
                b.extend_from_slice(&((c.message_index_offsets.len() * 10) as u32).to_le_bytes());
                for (id, o) in &c.message_index_offsets {
                    b.extend_from_slice(&id.to_le_bytes());
                    b.extend_from_slice(&o.to_le_bytes());
                }
                b.extend_from_slice(&c.message_index_length.to_le_bytes());
                put_str(&mut b, "");
                b.extend_from_slice(&c.size.to_le_bytes());
                b.extend_from_slice(&c.size.to_le_bytes());
                record(op::CHUNK_INDEX, &b)
            })
            .collect();
        group(&mut summary, op::CHUNK_INDEX, &chunk_indexes);
        let summary_offset_start = summary_start + summary.len() as u64;
        for (opcode, start, length) in groups {
            let mut b = vec![opcode];
            b.extend_from_slice(&start.to_le_bytes());
            b.extend_from_slice(&length.to_le_bytes());
            summary.extend_from_slice(&record(op::SUMMARY_OFFSET, &b));
        }
        let mut footer = vec![op::FOOTER];
        footer.extend_from_slice(&20u64.to_le_bytes());
        footer.extend_from_slice(&summary_start.to_le_bytes());
        footer.extend_from_slice(&summary_offset_start.to_le_bytes());
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(&summary);
        hasher.update(&footer);
        footer.extend_from_slice(&hasher.finalize().to_le_bytes());
        self.raw(&summary)?;
        self.raw(&footer)?;
        self.raw(MAGIC)?;
        self.out.flush()?;
        Ok(self.out)
    }
}
