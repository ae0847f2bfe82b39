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

/// How chunks are compressed (one thread, fixed parameters: the same bytes
/// on every machine).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compression {
    /// One LZ4 frame (lz4's default level, 4 MB blocks, linked, no checksums).
    Lz4,
    /// One zstd frame at this level.
    Zstd(i32),
}

/// A chunk's uncompressed records, the messages' log times and offsets
/// in it by channel (id - 1), and the first and last log time.
#[derive(Default)]
pub struct Chunk {
    data: Vec<u8>,
    index: Vec<Vec<(u64, u64)>>,
    bounds: Option<(u64, u64)>,
}

/// Builds the chunks: a message is appended to the open chunk as one
/// record; the chunk is closed before the first message that finds it
/// larger than the chunk size. What it hands on goes to [`Container::chunk`]
/// in the same order (on this thread or another: the bytes are the same).
pub struct Chunker {
    chunk_size: usize,
    channels: usize,
    open: Chunk,
    /// Emptied chunks, for reuse.
    spare: Vec<Chunk>,
}

impl Chunker {
    /// Chunks of `chunk_size` uncompressed bytes for `channels` channels
    /// (ids 1..=channels).
    pub fn new(chunk_size: usize, channels: usize) -> Chunker {
        Chunker { chunk_size, channels, open: Chunk::default(), spare: Vec::new() }
    }

    /// One message on `channel`, log and publish time `time_ns`: `data`
    /// appends its bytes to the buffer it is given (the chunk's) and returns
    /// what it failed on, if anything; the record is then dropped. The chunk
    /// this message closed, if it did, comes back.
    pub fn message<E>(
        &mut self,
        channel: u16,
        sequence: u32,
        time_ns: u64,
        data: impl FnOnce(&mut Vec<u8>) -> Result<(), E>,
    ) -> Result<Option<Chunk>, E>
    where
        E: From<io::Error>,
    {
        let Some(ci) = (channel as usize).checked_sub(1).filter(|&i| i < self.channels) else {
            return Err(io::Error::other(format!("mcap: no channel {channel}")).into());
        };
        let full = if self.open.data.len() > self.chunk_size { self.take() } else { None };
        let c = &mut self.open;
        if c.index.len() < self.channels {
            c.index.resize_with(self.channels, Vec::new);
            c.data.reserve(self.chunk_size + (64 << 10));
        }
        let at = c.data.len();
        let mut h = [0u8; MESSAGE_HEADER_LEN];
        h[9..11].copy_from_slice(&channel.to_le_bytes());
        h[11..15].copy_from_slice(&sequence.to_le_bytes());
        h[15..23].copy_from_slice(&time_ns.to_le_bytes());
        h[23..31].copy_from_slice(&time_ns.to_le_bytes());
        c.data.extend_from_slice(&h);
        if let Err(e) = data(&mut c.data) {
            c.data.truncate(at);
            // a chunk this message closed stays open: the next message closes it
            if let Some(f) = full {
                let next = std::mem::replace(&mut self.open, f);
                self.spare.push(next);
            }
            return Err(e);
        }
        close_record(&mut c.data, at, OP_MESSAGE);
        c.index[ci].push((time_ns, at as u64));
        c.bounds = Some(c.bounds.map_or((time_ns, time_ns), |(s, e)| (s.min(time_ns), e.max(time_ns))));
        Ok(full)
    }

    /// The open chunk, if it has a message; a spare one is opened.
    pub fn take(&mut self) -> Option<Chunk> {
        self.open.bounds?;
        let next = self.spare.pop().unwrap_or_default();
        Some(std::mem::replace(&mut self.open, next))
    }

    /// A chunk [`Container::chunk`] has written, emptied for reuse.
    pub fn recycle(&mut self, mut c: Chunk) {
        c.data.clear();
        c.index.iter_mut().for_each(Vec::clear);
        c.bounds = None;
        self.spare.push(c);
    }
}

/// The writer. `W` gets the chunks whole and the other records in small
/// writes: give it a buffered one.
pub struct Container<W: Write> {
    out: W,
    /// Bytes written to `out`.
    pos: u64,
    /// CRC of the data section so far (from the magic on).
    data_crc: crc32fast::Hasher,
    /// The schema and channel records, again for the summary.
    schemas: Vec<u8>,
    channels: Vec<u8>,
    schema_count: u16,
    channel_count: u16,
    /// zstd's context, or none for lz4.
    zstd: Option<zstd::bulk::Compressor<'static>>,
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
    /// The magic and the header record (`profile`, `library`); chunks
    /// compressed as `compression` says.
    pub fn new(out: W, profile: &str, library: &str, compression: Compression) -> io::Result<Container<W>> {
        let mut c = Container {
            out,
            pos: 0,
            data_crc: crc32fast::Hasher::new(),
            schemas: Vec::new(),
            channels: Vec::new(),
            schema_count: 0,
            channel_count: 0,
            zstd: match compression {
                Compression::Zstd(level) => Some(zstd::bulk::Compressor::new(level)?),
                Compression::Lz4 => None,
            },
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
        self.counts.push(0);
        Ok(id)
    }

    /// The channels added so far (a [`Chunker`] for them: `Chunker::new(size, this)`).
    pub fn channel_count(&self) -> usize {
        usize::from(self.channel_count)
    }

    /// A chunk from the [`Chunker`], compressed, then its message indexes;
    /// its chunk index kept for the summary.
    pub fn chunk(&mut self, c: &Chunk) -> io::Result<()> {
        let Some((start, end)) = c.bounds else {
            return Ok(());
        };
        let crc = crc32fast::hash(&c.data);
        self.zbuf.clear();
        let cname = match &mut self.zstd {
            Some(z) => {
                self.zbuf.reserve(zstd::zstd_safe::compress_bound(c.data.len()));
                z.compress_to_buffer(&c.data[..], &mut self.zbuf)?;
                "zstd"
            }
            None => {
                // one LZ4 frame, no checksums (the chunk has its CRC), as the mcap crate writes it
                let mut e = lz4::EncoderBuilder::new()
                    .block_size(lz4::BlockSize::Max4MB)
                    .block_mode(lz4::BlockMode::Linked)
                    .checksum(lz4::ContentChecksum::NoChecksum)
                    .block_checksum(lz4::liblz4::BlockChecksum::NoBlockChecksum)
                    .build(std::mem::take(&mut self.zbuf))?;
                e.write_all(&c.data)?;
                let (z, r) = e.finish();
                self.zbuf = z;
                r?;
                "lz4"
            }
        };
        let chunk_start = self.pos;
        let mut b = std::mem::take(&mut self.rec);
        b.clear();
        b.push(OP_CHUNK);
        let len = 8 + 8 + 8 + 4 + 4 + cname.len() as u64 + 8 + self.zbuf.len() as u64;
        b.extend_from_slice(&len.to_le_bytes());
        b.extend_from_slice(&start.to_le_bytes());
        b.extend_from_slice(&end.to_le_bytes());
        b.extend_from_slice(&(c.data.len() as u64).to_le_bytes());
        b.extend_from_slice(&crc.to_le_bytes());
        put_str(&mut b, cname);
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
        for (i, entries) in c.index.iter().enumerate().filter(|(_, e)| !e.is_empty()) {
            let id = i as u16 + 1;
            offsets.push((id, index_start + b.len() as u64));
            let at = open_record(&mut b);
            b.extend_from_slice(&id.to_le_bytes());
            b.extend_from_slice(&((entries.len() * 16) as u32).to_le_bytes());
            for (t, o) in entries {
                b.extend_from_slice(&t.to_le_bytes());
                b.extend_from_slice(&o.to_le_bytes());
            }
            close_record(&mut b, at, OP_MESSAGE_INDEX);
            self.counts[i] += entries.len() as u64;
            self.message_count += entries.len() as u64;
        }
        self.put(&b)?;
        self.rec = b;
        self.bounds = Some(self.bounds.map_or((start, end), |(s, e)| (s.min(start), e.max(end))));

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
        put_str(ci, cname);
        ci.extend_from_slice(&(self.zbuf.len() as u64).to_le_bytes());
        ci.extend_from_slice(&(c.data.len() as u64).to_le_bytes());
        close_record(ci, at, OP_CHUNK_INDEX);
        self.chunk_count += 1;
        Ok(())
    }

    /// Where the file goes.
    pub fn out_mut(&mut self) -> &mut W {
        &mut self.out
    }

    /// The data end and the summary (after the last chunk); the writer, flushed.
    pub fn finish(mut self) -> io::Result<W> {
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
    fn file(compression: Compression) -> (Vec<u8>, Msgs) {
        let mut w = Container::new(Vec::new(), "", "test", compression).unwrap();
        let s = w.add_schema("a/msg/A", "ros2msg", b"uint8[] v").unwrap();
        let t = w.add_schema("b", "jsonschema", b"{}").unwrap();
        let chs = [w.add_channel(s, "/a", "cdr").unwrap(), w.add_channel(t, "/b", "json").unwrap(), w.add_channel(s, "/c", "cdr").unwrap()];
        assert_eq!((s, t, chs), (1, 2, [1, 2, 3]));
        let mut k = Chunker::new(200, w.channel_count());
        let mut msgs = Vec::new();
        for i in 0..100u32 {
            let ch = chs[(i % 7 % 3) as usize];
            let data: Vec<u8> = (0..(i % 40 + 1) as u8).collect();
            let r: io::Result<_> = k.message(ch, i, 1000 + u64::from(i) * 10, |b| {
                b.extend_from_slice(&data);
                Ok(())
            });
            if let Some(c) = r.unwrap() {
                w.chunk(&c).unwrap();
                k.recycle(c);
            }
            msgs.push((ch, i, 1000 + u64::from(i) * 10, data));
            // a message whose encoding fails leaves nothing, in a chunk
            // about to close or not
            if i % 10 == 5 {
                let r: io::Result<_> = k.message(chs[0], 999, 5000, |b| {
                    b.push(1);
                    Err(io::Error::other("no"))
                });
                assert!(r.is_err());
            }
        }
        assert!(k.message(9, 0, 0, |_| Ok::<(), io::Error>(())).is_err(), "an unknown channel");
        if let Some(c) = k.take() {
            w.chunk(&c).unwrap();
        }
        assert!(k.take().is_none());
        (w.finish().unwrap(), msgs)
    }

    #[test]
    fn the_mcap_crate_reads_it_back_with_every_crc_and_index() {
        for (compression, name) in [(Compression::Lz4, "lz4"), (Compression::Zstd(1), "zstd")] {
            reads_back(compression, name);
        }
    }

    fn reads_back(compression: Compression, name: &str) {
        let (bytes, msgs) = file(compression);
        assert_eq!(bytes, file(compression).0, "the same bytes twice");
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
            assert_eq!(ci.compression, name);
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

        // and the CRCs are checked: a byte changed in the first chunk's data is seen
        let at = s.chunk_indexes[0].chunk_start_offset as usize + 60;
        let mut bad = bytes.clone();
        bad[at] ^= 0x40;
        let mut r = LinearReader::new_with_options(LinearReaderOptions::default().with_validate_chunk_crcs(true));
        let mut cur = io::Cursor::new(&bad);
        let mut failed = false;
        while let Some(ev) = r.next_event() {
            match ev {
                Ok(LinearReadEvent::ReadRequest(n)) => {
                    let k = cur.read(r.insert(n)).unwrap();
                    r.notify_read(k);
                }
                Ok(_) => {}
                Err(_) => {
                    failed = true;
                    break;
                }
            }
        }
        assert!(failed, "a changed byte went unseen");
    }

    #[test]
    fn a_file_without_messages_reads_back() {
        let mut c = Container::new(Vec::new(), "", "test", Compression::Lz4).unwrap();
        let s = c.add_schema("a", "jsonschema", b"{}").unwrap();
        c.add_channel(s, "/a", "json").unwrap();
        assert!(Chunker::new(1 << 20, 1).take().is_none());
        let bytes = c.finish().unwrap();
        let s = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert_eq!((s.stats.unwrap().message_count, s.chunk_indexes.len(), s.channels.len()), (0, 0, 1));
        assert_eq!(mcap::MessageStream::new(&bytes).unwrap().count(), 0);
    }
}
