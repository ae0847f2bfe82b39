//! The MCAP container (<https://mcap.dev/spec>) of `replay --mcap`: the
//! header, schemas and channels, zstd chunks each followed by its message
//! indexes, a data end with the data section's CRC, and the summary
//! (schemas, channels, statistics, chunk indexes, summary offsets, footer
//! with its CRC), as the `mcap` crate's writer lays them out.
//!
//! Why not the crate's writer: it hands every record to the compressor in
//! about seven small writes (a CRC and a zstd stream call each), which cost
//! more than the compression. Here a message is appended to the open chunk's
//! buffer as one record, and a full chunk is compressed in one call
//! (`zstd::bulk`, one thread, a fixed level: the same bytes on every
//! machine) and written whole. The `mcap` crate's reader reads it back in
//! the tests (CRCs, indexes, summary).

use std::io::{self, Write};

/// The file's magic, at both ends.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

const OP_HEADER: u8 = 0x01;
const OP_FOOTER: u8 = 0x02;
const OP_SCHEMA: u8 = 0x03;
const OP_CHANNEL: u8 = 0x04;
const OP_MESSAGE: u8 = 0x05;
const OP_CHUNK: u8 = 0x06;
const OP_MESSAGE_INDEX: u8 = 0x07;
const OP_CHUNK_INDEX: u8 = 0x08;
const OP_STATISTICS: u8 = 0x0B;
const OP_SUMMARY_OFFSET: u8 = 0x0E;
const OP_DATA_END: u8 = 0x0F;

/// A message record's bytes before its data: opcode, length, channel,
/// sequence, log and publish time.
pub const MESSAGE_HEADER_LEN: usize = 1 + 8 + 2 + 4 + 8 + 8;

fn put_str(b: &mut Vec<u8>, s: &str) {
    b.extend_from_slice(&(s.len() as u32).to_le_bytes());
    b.extend_from_slice(s.as_bytes());
}

/// Opcode and length of a record whose content is `b[at + 9..]`, written
/// over the 9 bytes reserved at `at`.
fn close_record(b: &mut [u8], at: usize, op: u8) {
    let len = (b.len() - at - 9) as u64;
    b[at] = op;
    b[at + 1..at + 9].copy_from_slice(&len.to_le_bytes());
}

/// Reserves a record's opcode and length; [`close_record`] fills them.
fn open_record(b: &mut Vec<u8>) -> usize {
    let at = b.len();
    b.extend_from_slice(&[0; 9]);
    at
}

/// The writer. `W` gets the chunks whole and the other records in small
/// writes: give it a buffered one.
pub struct Container<W: Write> {
    out: W,
    /// Bytes written to `out`.
    pos: u64,
    /// CRC of the data section so far (from the magic on).
    data_crc: crc32fast::Hasher,
    chunk_size: usize,
    /// The schema and channel records, again for the summary.
    schemas: Vec<u8>,
    channels: Vec<u8>,
    schema_count: u16,
    channel_count: u16,
    /// The open chunk's uncompressed records.
    chunk: Vec<u8>,
    chunk_bounds: Option<(u64, u64)>,
    /// The open chunk's message index, by channel id - 1: (log time, offset).
    index: Vec<Vec<(u64, u64)>>,
    zstd: zstd::bulk::Compressor<'static>,
    zbuf: Vec<u8>,
    rec: Vec<u8>,
    /// Chunk index records, for the summary.
    chunk_indexes: Vec<u8>,
    chunk_count: u32,
    message_count: u64,
    bounds: Option<(u64, u64)>,
    /// Messages by channel id - 1.
    counts: Vec<u64>,
}

impl<W: Write> Container<W> {
    /// The magic and the header record (`profile`, `library`); chunks of
    /// `chunk_size` uncompressed bytes (a chunk is closed before the first
    /// message that finds it larger), zstd at `level`.
    pub fn new(out: W, profile: &str, library: &str, chunk_size: usize, level: i32) -> io::Result<Container<W>> {
        let mut c = Container {
            out,
            pos: 0,
            data_crc: crc32fast::Hasher::new(),
            chunk_size,
            schemas: Vec::new(),
            channels: Vec::new(),
            schema_count: 0,
            channel_count: 0,
            chunk: Vec::with_capacity(chunk_size + (64 << 10)),
            chunk_bounds: None,
            index: Vec::new(),
            zstd: zstd::bulk::Compressor::new(level)?,
            zbuf: Vec::new(),
            rec: Vec::with_capacity(4096),
            chunk_indexes: Vec::new(),
            chunk_count: 0,
            message_count: 0,
            bounds: None,
            counts: Vec::new(),
        };
        c.put(MAGIC)?;
        let mut b = std::mem::take(&mut c.rec);
        b.clear();
        let at = open_record(&mut b);
        put_str(&mut b, profile);
        put_str(&mut b, library);
        close_record(&mut b, at, OP_HEADER);
        c.put(&b)?;
        c.rec = b;
        Ok(c)
    }

    /// `bytes` to the data section.
    fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.data_crc.update(bytes);
        self.pos += bytes.len() as u64;
        self.out.write_all(bytes)
    }

    /// A schema (ids from 1, in the order added), written at once to the
    /// data section and again in the summary.
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> io::Result<u16> {
        self.schema_count += 1;
        let id = self.schema_count;
        let mut b = Vec::new();
        let at = open_record(&mut b);
        b.extend_from_slice(&id.to_le_bytes());
        put_str(&mut b, name);
        put_str(&mut b, encoding);
        b.extend_from_slice(&(data.len() as u32).to_le_bytes());
        b.extend_from_slice(data);
        close_record(&mut b, at, OP_SCHEMA);
        self.put(&b)?;
        self.schemas.extend_from_slice(&b);
        Ok(id)
    }

    /// A channel (ids from 1, in the order added; no metadata).
    pub fn add_channel(&mut self, schema: u16, topic: &str, message_encoding: &str) -> io::Result<u16> {
        self.channel_count += 1;
        let id = self.channel_count;
        let mut b = Vec::new();
        let at = open_record(&mut b);
        b.extend_from_slice(&id.to_le_bytes());
        b.extend_from_slice(&schema.to_le_bytes());
        put_str(&mut b, topic);
        put_str(&mut b, message_encoding);
        b.extend_from_slice(&0u32.to_le_bytes());
        close_record(&mut b, at, OP_CHANNEL);
        self.put(&b)?;
        self.channels.extend_from_slice(&b);
        self.index.push(Vec::new());
        self.counts.push(0);
        Ok(id)
    }

    /// One message on `channel` (an id [`Self::add_channel`] gave), log
    /// and publish time `time_ns`: `data` appends its bytes to the buffer it
    /// is given (the chunk's) and returns what it failed on, if anything; the
    /// record is then dropped.
    pub fn message<E>(
        &mut self,
        channel: u16,
        sequence: u32,
        time_ns: u64,
        data: impl FnOnce(&mut Vec<u8>) -> Result<(), E>,
    ) -> Result<(), E>
    where
        E: From<io::Error>,
    {
        let Some(ci) = (channel as usize).checked_sub(1).filter(|&i| i < self.index.len()) else {
            return Err(io::Error::other(format!("mcap: no channel {channel}")).into());
        };
        if self.chunk.len() > self.chunk_size {
            self.finish_chunk()?;
        }
        let at = self.chunk.len();
        let mut h = [0u8; MESSAGE_HEADER_LEN];
        h[9..11].copy_from_slice(&channel.to_le_bytes());
        h[11..15].copy_from_slice(&sequence.to_le_bytes());
        h[15..23].copy_from_slice(&time_ns.to_le_bytes());
        h[23..31].copy_from_slice(&time_ns.to_le_bytes());
        self.chunk.extend_from_slice(&h);
        if let Err(e) = data(&mut self.chunk) {
            self.chunk.truncate(at);
            return Err(e);
        }
        close_record(&mut self.chunk, at, OP_MESSAGE);
        self.index[ci].push((time_ns, at as u64));
        self.counts[ci] += 1;
        self.message_count += 1;
        let widen = |b: Option<(u64, u64)>| Some(b.map_or((time_ns, time_ns), |(s, e)| (s.min(time_ns), e.max(time_ns))));
        self.chunk_bounds = widen(self.chunk_bounds);
        self.bounds = widen(self.bounds);
        Ok(())
    }

    /// The open chunk, compressed, then its message indexes; its chunk
    /// index kept for the summary. Nothing when no chunk is open.
    fn finish_chunk(&mut self) -> io::Result<()> {
        let Some((start, end)) = self.chunk_bounds.take() else {
            return Ok(());
        };
        let crc = crc32fast::hash(&self.chunk);
        self.zbuf.clear();
        self.zbuf.reserve(zstd::zstd_safe::compress_bound(self.chunk.len()));
        self.zstd.compress_to_buffer(&self.chunk[..], &mut self.zbuf)?;
        let chunk_start = self.pos;
        let mut b = std::mem::take(&mut self.rec);
        b.clear();
        b.push(OP_CHUNK);
        let len = 8 + 8 + 8 + 4 + 4 + 4 + 8 + self.zbuf.len() as u64;
        b.extend_from_slice(&len.to_le_bytes());
        b.extend_from_slice(&start.to_le_bytes());
        b.extend_from_slice(&end.to_le_bytes());
        b.extend_from_slice(&(self.chunk.len() as u64).to_le_bytes());
        b.extend_from_slice(&crc.to_le_bytes());
        put_str(&mut b, "zstd");
        b.extend_from_slice(&(self.zbuf.len() as u64).to_le_bytes());
        self.put(&b)?;
        let z = std::mem::take(&mut self.zbuf);
        let r = self.put(&z);
        self.zbuf = z;
        r?;
        let chunk_length = self.pos - chunk_start;

        // the message indexes, by channel id, of the channels in this chunk
        let index_start = self.pos;
        let mut offsets = Vec::new();
        b.clear();
        for (i, entries) in self.index.iter_mut().enumerate().filter(|(_, e)| !e.is_empty()) {
            let id = i as u16 + 1;
            offsets.push((id, index_start + b.len() as u64));
            let at = open_record(&mut b);
            b.extend_from_slice(&id.to_le_bytes());
            b.extend_from_slice(&((entries.len() * 16) as u32).to_le_bytes());
            for (t, o) in entries.drain(..) {
                b.extend_from_slice(&t.to_le_bytes());
                b.extend_from_slice(&o.to_le_bytes());
            }
            close_record(&mut b, at, OP_MESSAGE_INDEX);
        }
        self.put(&b)?;
        self.rec = b;

        let ci = &mut self.chunk_indexes;
        let at = open_record(ci);
        ci.extend_from_slice(&start.to_le_bytes());
        ci.extend_from_slice(&end.to_le_bytes());
        ci.extend_from_slice(&chunk_start.to_le_bytes());
        ci.extend_from_slice(&chunk_length.to_le_bytes());
        ci.extend_from_slice(&((offsets.len() * 10) as u32).to_le_bytes());
        for (id, o) in offsets {
            ci.extend_from_slice(&id.to_le_bytes());
            ci.extend_from_slice(&o.to_le_bytes());
        }
        ci.extend_from_slice(&(self.pos - index_start).to_le_bytes());
        put_str(ci, "zstd");
        ci.extend_from_slice(&(self.zbuf.len() as u64).to_le_bytes());
        ci.extend_from_slice(&(self.chunk.len() as u64).to_le_bytes());
        close_record(ci, at, OP_CHUNK_INDEX);
        self.chunk_count += 1;
        self.chunk.clear();
        Ok(())
    }

    /// The last chunk, the data end and the summary; the writer, flushed.
    pub fn finish(mut self) -> io::Result<W> {
        self.finish_chunk()?;
        let crc = self.data_crc.clone().finalize();
        let mut b = Vec::new();
        let at = open_record(&mut b);
        b.extend_from_slice(&crc.to_le_bytes());
        close_record(&mut b, at, OP_DATA_END);
        self.put(&b)?;

        // the summary: its groups, then an offset record for each
        let summary_start = self.pos;
        let mut s = Vec::new();
        let mut groups = Vec::new();
        let mut group = |s: &mut Vec<u8>, op: u8, bytes: &[u8]| {
            if !bytes.is_empty() {
                groups.push((op, summary_start + s.len() as u64, bytes.len() as u64));
                s.extend_from_slice(bytes);
            }
        };
        group(&mut s, OP_SCHEMA, &self.schemas);
        group(&mut s, OP_CHANNEL, &self.channels);
        let mut st = Vec::new();
        let at = open_record(&mut st);
        let (t0, t1) = self.bounds.unwrap_or((0, 0));
        st.extend_from_slice(&self.message_count.to_le_bytes());
        st.extend_from_slice(&self.schema_count.to_le_bytes());
        st.extend_from_slice(&u32::from(self.channel_count).to_le_bytes());
        st.extend_from_slice(&0u32.to_le_bytes()); // attachments
        st.extend_from_slice(&0u32.to_le_bytes()); // metadata
        st.extend_from_slice(&self.chunk_count.to_le_bytes());
        st.extend_from_slice(&t0.to_le_bytes());
        st.extend_from_slice(&t1.to_le_bytes());
        let used: Vec<(u16, u64)> = self.counts.iter().enumerate().filter(|(_, &n)| n > 0).map(|(i, &n)| (i as u16 + 1, n)).collect();
        st.extend_from_slice(&((used.len() * 10) as u32).to_le_bytes());
        for (id, n) in used {
            st.extend_from_slice(&id.to_le_bytes());
            st.extend_from_slice(&n.to_le_bytes());
        }
        close_record(&mut st, at, OP_STATISTICS);
        group(&mut s, OP_STATISTICS, &st);
        group(&mut s, OP_CHUNK_INDEX, &self.chunk_indexes);
        let offsets_start = summary_start + s.len() as u64;
        for (op, start, len) in groups {
            let at = open_record(&mut s);
            s.push(op);
            s.extend_from_slice(&start.to_le_bytes());
            s.extend_from_slice(&len.to_le_bytes());
            close_record(&mut s, at, OP_SUMMARY_OFFSET);
        }
        // the footer; its CRC covers the summary and the footer up to itself
        s.push(OP_FOOTER);
        s.extend_from_slice(&20u64.to_le_bytes());
        s.extend_from_slice(&summary_start.to_le_bytes());
        s.extend_from_slice(&offsets_start.to_le_bytes());
        let crc = crc32fast::hash(&s);
        s.extend_from_slice(&crc.to_le_bytes());
        s.extend_from_slice(MAGIC);
        self.out.write_all(&s)?;
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
    use std::io::Read;

    /// (channel, sequence, time, data) of each message written.
    type Msgs = Vec<(u16, u32, u64, Vec<u8>)>;

    /// Three channels, messages of 1-40 bytes in chunks of 200.
    fn file() -> (Vec<u8>, Msgs) {
        let mut c = Container::new(Vec::new(), "", "test", 200, 1).unwrap();
        let s = c.add_schema("a/msg/A", "ros2msg", b"uint8[] v").unwrap();
        let t = c.add_schema("b", "jsonschema", b"{}").unwrap();
        let chs = [c.add_channel(s, "/a", "cdr").unwrap(), c.add_channel(t, "/b", "json").unwrap(), c.add_channel(s, "/c", "cdr").unwrap()];
        assert_eq!((s, t, chs), (1, 2, [1, 2, 3]));
        let mut msgs = Vec::new();
        for i in 0..100u32 {
            let ch = chs[(i % 7 % 3) as usize];
            let data: Vec<u8> = (0..(i % 40 + 1) as u8).collect();
            let r: io::Result<()> = c.message(ch, i, 1000 + u64::from(i) * 10, |b| {
                b.extend_from_slice(&data);
                Ok(())
            });
            r.unwrap();
            msgs.push((ch, i, 1000 + u64::from(i) * 10, data));
        }
        // a message whose encoding fails leaves nothing
        let r: io::Result<()> = c.message(chs[0], 999, 5000, |b| {
            b.push(1);
            Err(io::Error::other("no"))
        });
        assert!(r.is_err());
        assert!(c.message(9, 0, 0, |_| Ok::<(), io::Error>(())).is_err(), "an unknown channel");
        (c.finish().unwrap(), msgs)
    }

    #[test]
    fn the_mcap_crate_reads_it_back_with_every_crc_and_index() {
        let (bytes, msgs) = file();
        assert_eq!(bytes, file().0, "the same bytes twice");
        assert!(bytes.starts_with(MAGIC) && bytes.ends_with(MAGIC));

        // every record, chunk CRCs, the data section's and the summary's checked
        let mut r = LinearReader::new_with_options(
            LinearReaderOptions::default()
                .with_validate_chunk_crcs(true)
                .with_validate_data_section_crc(true)
                .with_validate_summary_section_crc(true),
        );
        let mut cur = io::Cursor::new(&bytes);
        let mut read: Msgs = Vec::new();
        while let Some(ev) = r.next_event() {
            match ev.unwrap() {
                LinearReadEvent::ReadRequest(n) => {
                    let k = cur.read(r.insert(n)).unwrap();
                    r.notify_read(k);
                }
                LinearReadEvent::Record { data, opcode } => {
                    if let mcap::records::Record::Message { header, data } = mcap::parse_record(opcode, data).unwrap() {
                        assert_eq!(header.log_time, header.publish_time);
                        read.push((header.channel_id, header.sequence, header.log_time, data.to_vec()));
                    }
                }
            }
        }
        assert_eq!(read, msgs);

        // the summary, and each chunk's message indexes pointing at its messages
        let s = mcap::Summary::read(&bytes).unwrap().unwrap();
        let st = s.stats.as_ref().unwrap();
        assert_eq!((st.message_count, st.schema_count, st.channel_count, st.chunk_count), (100, 2, 3, s.chunk_indexes.len() as u32));
        assert!(st.chunk_count > 5, "{st:?}");
        assert_eq!((st.message_start_time, st.message_end_time), (1000, 1990));
        assert_eq!(st.channel_message_counts.values().sum::<u64>(), 100);
        assert_eq!(s.channels.len(), 3);
        assert_eq!(s.schemas.len(), 2);
        let mut seen = Vec::new();
        for ci in &s.chunk_indexes {
            assert_eq!(ci.compression, "zstd");
            let idx = s.read_message_indexes(&bytes, ci).unwrap();
            for (ch, entries) in idx {
                for e in entries {
                    let m = s.seek_message(&bytes, ci, &e).unwrap();
                    assert_eq!((m.channel.id, m.log_time), (ch.id, e.log_time));
                    seen.push((m.channel.id, m.sequence, m.log_time, m.data.to_vec()));
                }
            }
        }
        seen.sort_by_key(|m| m.1);
        assert_eq!(seen, msgs);
        let streamed: Vec<u32> = mcap::MessageStream::new(&bytes).unwrap().map(|m| m.unwrap().sequence).collect();
        assert_eq!(streamed, (0..100).collect::<Vec<_>>());
    }

    #[test]
    fn a_file_without_messages_reads_back() {
        let mut c = Container::new(Vec::new(), "", "test", 1 << 20, 1).unwrap();
        let s = c.add_schema("a", "jsonschema", b"{}").unwrap();
        c.add_channel(s, "/a", "json").unwrap();
        let bytes = c.finish().unwrap();
        let s = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert_eq!((s.stats.unwrap().message_count, s.chunk_indexes.len(), s.channels.len()), (0, 0, 1));
        assert_eq!(mcap::MessageStream::new(&bytes).unwrap().count(), 0);
    }
}
