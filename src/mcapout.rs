//! `replay --mcap` / `evaluate --mcap`: a recording Foxglove and PlotJuggler open.
//!
//! Channels (see docs/mcap.md): the three a replay writes, a message per
//! estimate or input frame, are CDR as ROS 2 writes it, each described by a
//! `ros2msg` schema, which Foxglove and PlotJuggler decode without a ROS
//! install; `evaluate`'s attitudes beside the estimate are JSON with a
//! `jsonschema`.
//!
//! | topic | schema | one message per |
//! | --- | --- | --- |
//! | `/tf` | `tf2_msgs/msg/TFMessage` (CDR) | estimate: `world` (ENU) -> `base_link` (FLU) |
//! | `/gyrocomp/estimate` | `gyrocomp/msg/Estimate` (CDR) | estimate: attitude (NED/FRD), corrected rates, bias, temperature, mode, flags, aid sources (`EST_AID`) |
//! | `/can/rx` | `gyrocomp/msg/CanFrame` (CDR) | input frame pushed into the pipeline |
//! | `/truth/estimate` | `gyrocomp.Attitude` (JSON) | evaluated sample (`evaluate --input DIR --mcap`): the simulated truth |
//! | `/truth/tf` | `tf2_msgs/msg/TFMessage` (CDR) | evaluated sample: `world` -> `base_link_truth` |
//! | `/vqf/estimate`, `/vqf/tf` | `gyrocomp.Attitude` (JSON), `tf2_msgs/msg/TFMessage` (CDR) | evaluated sample (`evaluate --input DIR --peers --mcap`): VQF's attitude, `base_link_vqf` |
//!
//! Deterministic bytes: log and publish times are the frames' own timestamps
//! (the candump stamp of the frame that closed a sample), never the clock of
//! the run; the library string is gyrocomp's; chunks are 1 MiB, zstd level 1
//! on one thread ([`container`]). The file goes through [`OutFile`]: temp
//! and rename. A non-finite number is never written: it is an error naming
//! the topic and the time (so is a time past 2038, which a ROS 2 time's
//! 32-bit seconds cannot hold).

pub mod container;

use crate::adis::RawFrame;
use crate::estimator::mekf::Aid;
use crate::estimator::Estimate;
use crate::outfile::OutFile;
use container::{Chunk, Chunker, Compression, Container};
use serde::Serialize;
use std::io;
use std::path::Path;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::JoinHandle;

/// Uncompressed bytes per chunk (fixed: the chunking is part of the bytes).
pub const CHUNK_SIZE: usize = 1 << 20;
/// lz4: of what was measured the least time for the 10-minute replay
/// (docs/mcap.md: zstd level 1 makes the file a fifth smaller for 5 % more time).
pub const COMPRESSION: Compression = Compression::Lz4;
/// The parent frame of every transform (REP-103 `world`, ENU).
pub const WORLD_FRAME: &str = "world";
/// The vehicle frame (REP-103 `base_link`, FLU).
pub const VEHICLE_FRAME: &str = "base_link";

#[derive(Debug, thiserror::Error)]
pub enum McapError {
    #[error("{0}")]
    Io(#[from] io::Error),
    #[error("non-finite {what} on {topic} at t_us {t_us} (not written)")]
    NonFinite { topic: &'static str, what: &'static str, t_us: u64 },
    #[error("time past 2038 on {topic} at t_us {t_us} (a ROS 2 time's seconds are 32-bit; not written)")]
    Time { topic: &'static str, t_us: u64 },
    #[error("its directory {0} does not exist")]
    NoDir(String),
}

const TIME: &str = r#"{"type":"object","title":"time","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}}"#;

fn xyz(desc: &str) -> String {
    format!(
        r#"{{"type":"object","description":"{desc}","properties":{{"x":{{"type":"number"}},"y":{{"type":"number"}},"z":{{"type":"number"}}}}}}"#
    )
}

/// The line between a `ros2msg` schema's sections (as `ros2 bag` writes it).
const SECTION: &str = "================================================================================\n";

/// `builtin_interfaces/Time`, as each `ros2msg` schema below appends it.
fn ros_time_section() -> String {
    format!("{SECTION}MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")
}

/// Schema names of the CDR channels.
pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
pub const ESTIMATE: &str = "gyrocomp/msg/Estimate";
pub const CAN_FRAME: &str = "gyrocomp/msg/CanFrame";

/// `tf2_msgs/msg/TFMessage` as ROS 2 defines it (the dependencies after
/// it), which Foxglove's 3D panel reads as transforms.
pub fn tf_message_schema() -> String {
    format!(
        concat!(
            "geometry_msgs/TransformStamped[] transforms\n",
            "{s}MSG: geometry_msgs/TransformStamped\n",
            "std_msgs/Header header\n",
            "string child_frame_id\n",
            "geometry_msgs/Transform transform\n",
            "{s}MSG: std_msgs/Header\n",
            "builtin_interfaces/Time stamp\n",
            "string frame_id\n",
            "{t}",
            "{s}MSG: geometry_msgs/Transform\n",
            "geometry_msgs/Vector3 translation\n",
            "geometry_msgs/Quaternion rotation\n",
            "{s}MSG: geometry_msgs/Vector3\n",
            "float64 x\nfloat64 y\nfloat64 z\n",
            "{s}MSG: geometry_msgs/Quaternion\n",
            "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
        ),
        s = SECTION,
        t = ros_time_section()
    )
}

/// `gyrocomp/msg/Estimate` (`ros2msg`, messages `cdr`): the fields in
/// [`estimate_cdr`]'s order, the flags as `flag.<name>` booleans, the aid
/// sources as `aid.<name>` codes.
pub fn estimate_schema() -> String {
    let flags: String = FLAG_NAMES.iter().map(|(n, b)| format!("bool {n} # bit {} of flags\n", b.trailing_zeros())).collect();
    let aid: String = Aid::ALL
        .iter()
        .enumerate()
        .map(|(i, a)| format!("uint8 {} # bits {}-{} of aid_status: {AID_CODES_TEXT}\n", a.name(), 2 * i, 2 * i + 1))
        .collect();
    format!(
        concat!(
            "# One gyrocomp estimate: attitude in NED (Z-Y-X Euler of the FRD body, deg), corrected rates and bias (FRD, deg/s), temperature (deg C), mode, status flags and aid sources\n",
            "builtin_interfaces/Time timestamp\n",
            "float64 t # s since the first sample, by the sample counter\n",
            "uint16 cnt # DATA_CNT\n",
            "float32 roll # deg\n",
            "float32 pitch # deg\n",
            "float32 yaw # deg, from north\n",
            "gyrocomp/Vector3f rate # bias-corrected rate, FRD, deg/s\n",
            "gyrocomp/Vector3f bias # gyro bias, FRD, deg/s\n",
            "float32 temp # deg C\n",
            "uint8 mode # 0 fusion with bias learning, 1 aided, 2 gyro only\n",
            "float32 accel_ratio # |a| / g0\n",
            "uint16 flags # the EST_STATUS flag word\n",
            "gyrocomp/Flags flag # each flag of flags\n",
            "uint32 aid_status # the EST_AID status word: 2 bits per aid source of the default filter\n",
            "float32 aid_worst_ratio # the largest test ratio of the aid sources at the last update tick, as EST_AID's WorstRatio (0..655.35, saturating)\n",
            "gyrocomp/AidSources aid # what each aid source of the default filter did at the last update tick\n",
            "uint8 invalid # the fields not estimated (a reduced-axis unit; 0 all valid), EST_AID's Invalid* bits: bit 0 rate.x and bias.x, 1 y, 2 z, 3 roll, 4 pitch, 5 yaw, 6 temp; an invalid field is 0\n",
            "{time}",
            "{s}MSG: gyrocomp/Vector3f\n",
            "float32 x\nfloat32 y\nfloat32 z\n",
            "{s}MSG: gyrocomp/Flags\n",
            "{flags}",
            "{s}MSG: gyrocomp/AidSources\n",
            "{aid}"
        ),
        time = ros_time_section(),
        s = SECTION,
        flags = flags,
        aid = aid
    )
}

/// `gyrocomp/msg/CanFrame` (`ros2msg`, messages `cdr`; see [`can_cdr`]).
pub fn can_frame_schema() -> String {
    format!(
        concat!(
            "# A raw CAN frame as read from the candump log\n",
            "builtin_interfaces/Time timestamp\n",
            "uint32 id # arbitration ID\n",
            "bool extended # 29-bit ID\n",
            "bool remote # RTR\n",
            "bool fd # CAN FD\n",
            "uint8 len # payload bytes (DLC)\n",
            "uint8[] data # payload bytes\n",
            "{}"
        ),
        ros_time_section()
    )
}

/// `gyrocomp.Attitude`: a reference (truth) or a peer (VQF) beside the estimate.
pub fn attitude_schema() -> String {
    format!(
        r#"{{"title":"gyrocomp.Attitude","description":"An attitude beside gyrocomp's (the simulated truth, a peer filter): Z-Y-X Euler of the FRD body in NED (deg) and the bias (FRD, deg/s; the truth's, absent for a peer)","type":"object","properties":{{"timestamp":{TIME},"t":{{"type":"number"}},"roll":{{"type":"number"}},"pitch":{{"type":"number"}},"yaw":{{"type":"number"}},"bias":{}}}}}"#,
        xyz("gyro bias, FRD, deg/s")
    )
}

/// The flags as `gyrocomp/msg/Estimate`'s `flag` names them.
pub const FLAG_NAMES: [(&str, u16); 14] = {
    use crate::estimator::flags::*;
    [
        ("suspect", SUSPECT),
        ("warmup", WARMUP),
        ("learning", LEARNING),
        ("resync", RESYNC),
        ("jerk", JERK),
        ("thermal_clamp", THERMAL_CLAMP),
        ("rate_sat", RATE_SAT),
        ("bus_silent", BUS_SILENT),
        ("standstill", STANDSTILL),
        ("gated", GATED),
        ("tx_drop", TX_DROP),
        ("relevel", RELEVEL),
        ("mag_disturbed", MAG_DISTURBED),
        ("speed_aided", SPEED_AIDED),
    ]
};

/// The meaning of an `aid.<name>` code (the DBC's `VAL_`).
const AID_CODES_TEXT: &str = "0 not applicable, 1 fused, 2 refused by the innovation gate";

#[derive(Serialize)]
struct Time {
    sec: u64,
    nsec: u32,
}

impl Time {
    fn from_us(t_us: u64) -> Time {
        Time { sec: t_us / 1_000_000, nsec: (t_us % 1_000_000) as u32 * 1000 }
    }
}

#[derive(Serialize)]
struct Xyz {
    x: f32,
    y: f32,
    z: f32,
}

impl From<[f64; 3]> for Xyz {
    fn from(v: [f64; 3]) -> Xyz {
        Xyz { x: v[0] as f32, y: v[1] as f32, z: v[2] as f32 }
    }
}

#[derive(Serialize)]
struct AttitudeMsg {
    timestamp: Time,
    t: f64,
    roll: f32,
    pitch: f32,
    yaw: f32,
    #[serde(skip_serializing_if = "Option::is_none")]
    bias: Option<Xyz>,
}

/// The CDR encapsulation header: plain CDR, little-endian.
const CDR_LE: [u8; 4] = [0, 1, 0, 0];

/// Fixed-layout CDR: each message is built in an array on the stack at
/// the offsets its schema gives (every field at its natural alignment,
/// counted from the end of the encapsulation header: `put` takes that
/// offset) and appended in one piece.
fn put<const N: usize>(m: &mut [u8], at: usize, v: [u8; N]) {
    m[4 + at..4 + at + N].copy_from_slice(&v);
}

/// `builtin_interfaces/Time` at `at` (seconds checked by [`ros_sec`]).
fn put_time(m: &mut [u8], at: usize, sec: i32, t_us: u64) {
    put(m, at, sec.to_le_bytes());
    put(m, at + 4, ((t_us % 1_000_000) as u32 * 1000).to_le_bytes());
}

fn f32le(v: f64) -> [u8; 4] {
    (v as f32).to_le_bytes()
}

/// A ROS 2 `builtin_interfaces/Time`'s seconds (`int32`), or the error
/// naming the topic when `t_us` is past 2038.
fn ros_sec(topic: Topic, t_us: u64) -> Result<i32, McapError> {
    i32::try_from(t_us / 1_000_000).map_err(|_| McapError::Time { topic: topic.name(), t_us })
}

/// `tf2_msgs/msg/TFMessage` with one transform `world` -> `child` and no
/// translation, up to its rotation, stamped 0: built once per channel;
/// [`tf_cdr`] stamps a copy and appends the rotation.
fn tf_head(child: &str) -> Vec<u8> {
    let mut b = CDR_LE.to_vec();
    let string = |b: &mut Vec<u8>, s: &str| {
        b.resize(4 + (b.len() - 4).div_ceil(4) * 4, 0);
        b.extend_from_slice(&(s.len() as u32 + 1).to_le_bytes());
        b.extend_from_slice(s.as_bytes());
        b.push(0);
    };
    b.extend_from_slice(&1u32.to_le_bytes()); // one transform
    b.extend_from_slice(&[0; 8]); // header.stamp
    string(&mut b, WORLD_FRAME); // header.frame_id
    string(&mut b, child); // child_frame_id
    b.resize(4 + (b.len() - 4).div_ceil(8) * 8, 0);
    b.extend_from_slice(&[0; 24]); // translation
    b
}

/// A transform from [`tf_head`]: stamped, `q` (`[w, x, y, z]`) as its rotation.
fn tf_cdr(b: &mut Vec<u8>, head: &[u8], sec: i32, t_us: u64, q: [f64; 4]) {
    let at = b.len();
    b.extend_from_slice(head);
    put_time(&mut b[at..], 4, sec, t_us);
    for v in [q[1], q[2], q[3], q[0]] {
        b.extend_from_slice(&v.to_le_bytes());
    }
}

/// Bytes of a `gyrocomp/msg/Estimate` in CDR, with the header.
const ESTIMATE_LEN: usize = 4 + 92 + Aid::ALL.len() + 1;

/// `gyrocomp/msg/Estimate` as CDR (109 bytes with the header).
fn estimate_cdr(b: &mut Vec<u8>, sec: i32, e: &Estimate) {
    let mut m = [0u8; ESTIMATE_LEN];
    m[..4].copy_from_slice(&CDR_LE);
    put_time(&mut m, 0, sec, e.t_us);
    put(&mut m, 8, e.t.to_le_bytes());
    put(&mut m, 16, e.cnt.to_le_bytes());
    for (i, v) in [e.roll, e.pitch, e.yaw].into_iter().chain(e.rate).chain(e.bias).chain([e.temp]).enumerate() {
        put(&mut m, 20 + 4 * i, f32le(v));
    }
    m[4 + 60] = e.mode;
    put(&mut m, 64, f32le(e.ratio));
    put(&mut m, 68, e.flags.to_le_bytes());
    for (i, (_, bit)) in FLAG_NAMES.iter().enumerate() {
        m[4 + 70 + i] = u8::from(e.flags & bit != 0);
    }
    put(&mut m, 84, (e.aid.status & crate::output::AID_MASK).to_le_bytes());
    put(&mut m, 88, f32le(crate::output::ratio_sent(e.aid.worst_ratio)));
    for (i, a) in Aid::ALL.into_iter().enumerate() {
        m[4 + 92 + i] = e.aid.code(a) as u8;
    }
    m[ESTIMATE_LEN - 1] = e.invalid;
    b.extend_from_slice(&m);
}

/// `gyrocomp/msg/CanFrame` as CDR: 24 bytes and the payload.
fn can_cdr(b: &mut Vec<u8>, sec: i32, t_us: u64, f: &RawFrame<'_>) {
    let n = f.data.len().min(255);
    let mut m = [0u8; 24];
    m[..4].copy_from_slice(&CDR_LE);
    put_time(&mut m, 0, sec, t_us);
    put(&mut m, 8, f.id.to_le_bytes());
    put(&mut m, 12, [u8::from(f.extended), u8::from(f.remote), u8::from(f.fd), n as u8]);
    put(&mut m, 16, (n as u32).to_le_bytes());
    b.extend_from_slice(&m);
    b.extend_from_slice(&f.data[..n]);
}

/// `[w, x, y, z]` of the FLU body (`base_link`) in ENU (`world`), REP-103:
/// `q_enu_flu = q_enu_ned * q_ned_frd * q_frd_flu`, where ENU from NED is a
/// half turn about (1, 1, 0)/sqrt(2) (swap x and y, negate z) and FRD from
/// FLU a half turn about x. Normalised, with `w >= 0`.
pub fn quat_enu_flu(roll_deg: f64, pitch_deg: f64, yaw_deg: f64) -> [f64; 4] {
    use crate::estimator::quat;
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let ned_frd = quat::from_euler(roll_deg.to_radians(), pitch_deg.to_radians(), yaw_deg.to_radians());
    let mut q = quat::mul(&quat::mul(&[0.0, h, h, 0.0], &ned_frd), &[0.0, 1.0, 0.0, 0.0]);
    quat::normalise(&mut q);
    q
}

/// Topics of one recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Topic {
    Tf,
    Estimate,
    CanRx,
    TruthTf,
    TruthEstimate,
    VqfTf,
    VqfEstimate,
}

impl Topic {
    pub const fn name(self) -> &'static str {
        match self {
            Topic::Tf => "/tf",
            Topic::Estimate => "/gyrocomp/estimate",
            Topic::CanRx => "/can/rx",
            Topic::TruthTf => "/truth/tf",
            Topic::TruthEstimate => "/truth/estimate",
            Topic::VqfTf => "/vqf/tf",
            Topic::VqfEstimate => "/vqf/estimate",
        }
    }
    const ALL: [Topic; 7] =
        [Topic::Tf, Topic::Estimate, Topic::CanRx, Topic::TruthTf, Topic::TruthEstimate, Topic::VqfTf, Topic::VqfEstimate];
}

/// The MCAP being written; see the module docs. Messages are encoded into
/// chunks on the caller's thread; a thread of its own compresses and writes
/// each full chunk, in order (the same bytes as on one thread).
pub struct McapFile {
    chunker: Chunker,
    /// Channel id and the next sequence number, by `Topic as usize`.
    ch: [Option<(u16, u32)>; 7],
    /// A transform channel's message up to its rotation ([`tf_head`]), by `Topic as usize`.
    tf_heads: [Vec<u8>; 7],
    /// Full chunks to the writing thread, and back emptied for reuse.
    tx: Option<SyncSender<Chunk>>,
    back: Receiver<Chunk>,
    writer: Option<JoinHandle<io::Result<Container<OutFile>>>>,
}

impl McapFile {
    /// Start `dest` with the replay's channels, plus `/truth/*` and `/vqf/*`
    /// when asked for (evaluate). A directory, or a name whose
    /// directory does not exist, is refused before anything is created.
    pub fn create(dest: &Path, truth: bool, vqf: bool) -> Result<McapFile, McapError> {
        if let Some(dir) = dest.parent().filter(|d| !d.as_os_str().is_empty()) {
            if !dir.is_dir() {
                return Err(McapError::NoDir(dir.display().to_string()));
            }
        }
        let out = OutFile::create(dest)?;
        let library = format!("gyrocomp {}", env!("CARGO_PKG_VERSION"));
        let mut w = Container::new(out, "", &library, COMPRESSION)?;
        let tf = w.add_schema(TF_MESSAGE, "ros2msg", tf_message_schema().as_bytes())?;
        let est = w.add_schema(ESTIMATE, "ros2msg", estimate_schema().as_bytes())?;
        let can = w.add_schema(CAN_FRAME, "ros2msg", can_frame_schema().as_bytes())?;
        let att = if truth || vqf { Some(w.add_schema("gyrocomp.Attitude", "jsonschema", attitude_schema().as_bytes())?) } else { None };
        let mut ch = [None; 7];
        for t in Topic::ALL {
            let (schema, encoding) = match (t, att) {
                (Topic::Tf, _) => (tf, "cdr"),
                (Topic::Estimate, _) => (est, "cdr"),
                (Topic::CanRx, _) => (can, "cdr"),
                (Topic::TruthTf, _) if truth => (tf, "cdr"),
                (Topic::TruthEstimate, Some(att)) if truth => (att, "json"),
                (Topic::VqfTf, _) if vqf => (tf, "cdr"),
                (Topic::VqfEstimate, Some(att)) if vqf => (att, "json"),
                _ => continue,
            };
            ch[t as usize] = Some((w.add_channel(schema, t.name(), encoding)?, 0));
        }
        let chunker = Chunker::new(CHUNK_SIZE, w.channel_count());
        let (tx, rx) = sync_channel::<Chunk>(2);
        let (back_tx, back) = sync_channel::<Chunk>(4);
        let writer = std::thread::Builder::new().name("mcap".into()).spawn(move || {
            for c in rx {
                w.chunk(&c)?;
                // the disk writes while the replay runs, not all in commit's sync
                w.out_mut().start_writeback()?;
                let _ = back_tx.try_send(c);
            }
            Ok(w)
        })?;
        Ok(McapFile { chunker, ch, tf_heads: Default::default(), tx: Some(tx), back, writer: Some(writer) })
    }

    /// A full chunk to the writing thread; its error if it stopped on one.
    fn send(&mut self, c: Chunk) -> Result<(), McapError> {
        while let Ok(e) = self.back.try_recv() {
            self.chunker.recycle(e);
        }
        match &self.tx {
            Some(tx) if tx.send(c).is_ok() => Ok(()),
            _ => Err(self.stop().err().unwrap_or_else(|| io::Error::other("the mcap writer stopped")).into()),
        }
    }

    /// No more chunks: the writing thread's container, or its error.
    fn stop(&mut self) -> io::Result<Container<OutFile>> {
        self.tx = None;
        match self.writer.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(io::Error::other("the mcap writer panicked")),
            None => Err(io::Error::other("the mcap writer already stopped")),
        }
    }

    /// The next message on `topic` (nothing when this file has no such
    /// channel): `data` appends its bytes.
    fn put(&mut self, topic: Topic, t_us: u64, data: impl FnOnce(&mut Vec<u8>) -> Result<(), McapError>) -> Result<(), McapError> {
        let Some((id, seq)) = self.ch[topic as usize].as_mut() else {
            return Ok(());
        };
        let (id, s) = (*id, *seq);
        *seq = seq.wrapping_add(1);
        match self.chunker.message(id, s, t_us.saturating_mul(1000), data)? {
            Some(full) => self.send(full),
            None => Ok(()),
        }
    }

    fn finite(topic: Topic, what: &'static str, t_us: u64, v: &[f64]) -> Result<(), McapError> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(McapError::NonFinite { topic: topic.name(), what, t_us })
        }
    }

    /// A transform `world` -> `child` from NED/FRD Euler angles (deg).
    fn tf(&mut self, topic: Topic, child: &str, t_us: u64, rpy: [f64; 3]) -> Result<(), McapError> {
        Self::finite(topic, "attitude", t_us, &rpy)?;
        let q = quat_enu_flu(rpy[0], rpy[1], rpy[2]);
        Self::finite(topic, "quaternion", t_us, &q)?;
        let sec = ros_sec(topic, t_us)?;
        let i = topic as usize;
        if self.tf_heads[i].is_empty() {
            self.tf_heads[i] = tf_head(child);
        }
        let head = std::mem::take(&mut self.tf_heads[i]);
        let r = self.put(topic, t_us, |b| {
            tf_cdr(b, &head, sec, t_us, q);
            Ok(())
        });
        self.tf_heads[i] = head;
        r
    }

    /// One estimate: `/tf` and `/gyrocomp/estimate`.
    pub fn estimate(&mut self, e: &Estimate) -> Result<(), McapError> {
        let topic = Topic::Estimate;
        Self::finite(topic, "number", e.t_us, &[e.t, e.roll, e.pitch, e.yaw, e.temp, e.ratio])?;
        Self::finite(topic, "rate", e.t_us, &e.rate)?;
        Self::finite(topic, "bias", e.t_us, &e.bias)?;
        let sec = ros_sec(topic, e.t_us)?;
        self.tf(Topic::Tf, VEHICLE_FRAME, e.t_us, [e.roll, e.pitch, e.yaw])?;
        self.put(topic, e.t_us, |b| {
            estimate_cdr(b, sec, e);
            Ok(())
        })
    }

    /// One input frame on `/can/rx`.
    pub fn can(&mut self, t_us: u64, f: &RawFrame<'_>) -> Result<(), McapError> {
        let sec = ros_sec(Topic::CanRx, t_us)?;
        self.put(Topic::CanRx, t_us, |b| {
            can_cdr(b, sec, t_us, f);
            Ok(())
        })
    }

    /// The truth (`/truth/*`, child `base_link_truth`) at `t_us`: NED/FRD
    /// Euler (deg) and the true bias (FRD, deg/s).
    pub fn truth(&mut self, t_us: u64, t: f64, rpy: [f64; 3], bias: [f64; 3]) -> Result<(), McapError> {
        self.beside(Topic::TruthTf, Topic::TruthEstimate, "base_link_truth", t_us, t, rpy, Some(bias))
    }

    /// VQF's attitude (`/vqf/*`, child `base_link_vqf`) at `t_us`: NED/FRD Euler, deg.
    pub fn vqf(&mut self, t_us: u64, t: f64, rpy: [f64; 3]) -> Result<(), McapError> {
        self.beside(Topic::VqfTf, Topic::VqfEstimate, "base_link_vqf", t_us, t, rpy, None)
    }

    #[allow(clippy::too_many_arguments)]
    fn beside(
        &mut self,
        tf: Topic,
        est: Topic,
        child: &str,
        t_us: u64,
        t: f64,
        rpy: [f64; 3],
        bias: Option<[f64; 3]>,
    ) -> Result<(), McapError> {
        Self::finite(est, "number", t_us, &[t])?;
        if let Some(b) = &bias {
            Self::finite(est, "bias", t_us, b)?;
        }
        self.tf(tf, child, t_us, rpy)?;
        let msg = AttitudeMsg {
            timestamp: Time::from_us(t_us),
            t,
            roll: rpy[0] as f32,
            pitch: rpy[1] as f32,
            yaw: rpy[2] as f32,
            bias: bias.map(Xyz::from),
        };
        self.put(est, t_us, |b| serde_json::to_writer(b, &msg).map_err(|e| McapError::Io(io::Error::other(e))))
    }

    /// Write the summary and footer, then rename over the destination.
    pub fn commit(mut self) -> Result<(), McapError> {
        if let Some(c) = self.chunker.take() {
            self.send(c)?;
        }
        self.stop()?.finish()?.commit()?;
        Ok(())
    }
}

impl Drop for McapFile {
    /// Not committed (a failed run): the writing thread stops and drops its
    /// file, which removes the temporary file, before this returns.
    fn drop(&mut self) {
        self.tx = None;
        if let Some(h) = self.writer.take() {
            let _ = h.join();
        }
    }
}

/// The [`crate::pipeline::Sink`] part of `replay --mcap`: each estimate and
/// input frame encoded as it comes (on the replay's writing thread; the
/// compression has a thread of its own, see [`McapFile`]). The first error
/// stops the recording and comes back from [`McapSink::finish`].
pub struct McapSink {
    file: McapFile,
    err: Option<McapError>,
}

impl McapSink {
    pub fn new(file: McapFile) -> McapSink {
        McapSink { file, err: None }
    }

    pub fn output(&mut self, e: &Estimate) {
        if self.err.is_none() {
            self.err = self.file.estimate(e).err();
        }
    }

    pub fn input(&mut self, t_us: u64, f: &RawFrame<'_>) {
        if self.err.is_none() {
            // replay keeps at most 8 payload bytes (docs/mcap.md)
            let f = RawFrame { data: &f.data[..f.data.len().min(8)], ..*f };
            self.err = self.file.can(t_us, &f).err();
        }
    }

    /// Everything written: the file, ready for [`McapFile::commit`], or the first error.
    pub fn finish(self) -> Result<McapFile, McapError> {
        match self.err {
            Some(e) => Err(e),
            None => Ok(self.file),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est() -> Estimate {
        Estimate {
            cnt: 7,
            t_us: 1_700_000_000_123_456,
            t: 1.5,
            roll: 0.0,
            pitch: 0.0,
            yaw: 0.0,
            rate: [0.5, -0.25, 1.0],
            bias: [0.1, 0.2, -0.3],
            mode: 1,
            temp: 25.5,
            flags: crate::estimator::flags::STANDSTILL | crate::estimator::flags::SUSPECT,
            ratio: 1.0,
            // zero_velocity fused, zero_rate refused; a ratio past WorstRatio's range
            aid: crate::estimator::mekf::AidWord { status: 0b1001, worst_ratio: 1e9 },
            invalid: 0,
        }
    }

    #[test]
    fn north_level_is_a_quarter_turn_about_up_in_enu() {
        // x forward pointing north = ENU +y: yaw +90 deg about ENU z
        let q = quat_enu_flu(0.0, 0.0, 0.0);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for (a, b) in q.iter().zip([h, 0.0, 0.0, h]) {
            assert!((a - b).abs() < 1e-15, "{q:?}");
        }
        // heading east (NED yaw 90) is ENU yaw 0: the identity
        let q = quat_enu_flu(0.0, 0.0, 90.0);
        assert!((q[0] - 1.0).abs() < 1e-12 && q[1..].iter().all(|v| v.abs() < 1e-12), "{q:?}");
        // nose up (NED pitch +10) heading east: FLU pitched about its y (left)
        // by -10 deg in ENU (a right-handed turn about left lowers the nose)
        let q = quat_enu_flu(0.0, 10.0, 90.0);
        let s = (-5f64).to_radians().sin_cos();
        assert!((q[0] - s.1).abs() < 1e-12 && (q[2] - s.0).abs() < 1e-12 && q[1].abs() < 1e-12 && q[3].abs() < 1e-12, "{q:?}");
    }

    #[test]
    fn quaternions_are_unit_norm() {
        for &(r, p, y) in &[(10.0, -20.0, 30.0), (179.0, 89.0, -179.0), (-45.0, 0.5, 270.0)] {
            let q = quat_enu_flu(r, p, y);
            let n: f64 = q.iter().map(|v| v * v).sum();
            assert!((n - 1.0).abs() < 1e-12 && q[0] >= 0.0);
        }
    }

    /// The fields of a `ros2msg` schema's first (or `MSG: name`) section: (type, name).
    fn fields(schema: &str, section: Option<&str>) -> Vec<(String, String)> {
        let mut parts = schema.split(SECTION);
        let text = match section {
            None => parts.next().unwrap(),
            Some(n) => parts.find(|p| p.starts_with(&format!("MSG: {n}\n"))).unwrap(),
        };
        text.lines()
            .map(|l| l.split('#').next().unwrap().trim())
            .filter(|l| !l.is_empty() && !l.starts_with("MSG:"))
            .map(|l| {
                let mut w = l.split(' ');
                (w.next().unwrap().to_string(), w.next().unwrap().to_string())
            })
            .collect()
    }

    #[test]
    fn messages_encode_as_the_schemas_say() {
        let e = est();
        let mut b = Vec::new();
        estimate_cdr(&mut b, ros_sec(Topic::Estimate, e.t_us).unwrap(), &e);
        assert_eq!(b.len(), 109);
        assert_eq!(b[..4], CDR_LE);
        let m = &b[4..];
        let u32at = |i: usize| u32::from_le_bytes(m[i..i + 4].try_into().unwrap());
        let f32at = |i: usize| f32::from_le_bytes(m[i..i + 4].try_into().unwrap());
        assert_eq!((u32at(0), u32at(4)), (1_700_000_000, 123_456_000));
        assert_eq!(f64::from_le_bytes(m[8..16].try_into().unwrap()), 1.5);
        assert_eq!(u16::from_le_bytes([m[16], m[17]]), 7);
        assert_eq!([20, 24, 28].map(f32at), [0.0; 3]);
        assert_eq!([32, 36, 40, 44, 48, 52].map(f32at), [0.5, -0.25, 1.0, 0.1, 0.2, -0.3]);
        assert_eq!((f32at(56), m[60], f32at(64)), (25.5, 1, 1.0));
        assert_eq!(u16::from_le_bytes([m[68], m[69]]), 257);
        let on: Vec<&str> = FLAG_NAMES.iter().zip(&m[70..84]).filter(|(_, &v)| v == 1).map(|((n, _), _)| *n).collect();
        assert_eq!(on, ["suspect", "standstill"]);
        assert_eq!((u32at(84), f32at(88)), (9, 655.35));
        assert_eq!(m[92..104], [1, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(m[104], 0, "all valid");
        // the schema declares these fields in this order
        let schema = estimate_schema();
        let names: Vec<String> = fields(&schema, None).into_iter().map(|(_, n)| n).collect();
        let want = [
            "timestamp",
            "t",
            "cnt",
            "roll",
            "pitch",
            "yaw",
            "rate",
            "bias",
            "temp",
            "mode",
            "accel_ratio",
            "flags",
            "flag",
            "aid_status",
            "aid_worst_ratio",
            "aid",
            "invalid",
        ];
        assert_eq!(names, want);
        let flags = fields(&schema, Some("gyrocomp/Flags"));
        assert_eq!(flags.len(), FLAG_NAMES.len());
        assert!(flags.iter().zip(FLAG_NAMES).all(|((t, n), (f, _))| t == "bool" && n == f), "{flags:?}");
        let aid = fields(&schema, Some("gyrocomp/AidSources"));
        assert!(aid.len() == Aid::ALL.len() && aid.iter().zip(Aid::ALL).all(|((t, n), a)| t == "uint8" && n == a.name()), "{aid:?}");
        assert_eq!(fields(&schema, Some("gyrocomp/Vector3f")).len(), 3);
        assert_eq!(fields(&schema, Some("builtin_interfaces/Time")).len(), 2);

        let data = [1u8, 2, 0xff];
        b.clear();
        can_cdr(
            &mut b,
            ros_sec(Topic::CanRx, 5).unwrap(),
            5,
            &RawFrame { id: 0x100, extended: false, remote: true, fd: false, data: &data },
        );
        assert_eq!(b, [0, 1, 0, 0, 0, 0, 0, 0, 0x88, 0x13, 0, 0, 0, 1, 0, 0, 0, 1, 0, 3, 3, 0, 0, 0, 1, 2, 0xff]);
        let names: Vec<String> = fields(&can_frame_schema(), None).into_iter().map(|(_, n)| n).collect();
        assert_eq!(names, ["timestamp", "id", "extended", "remote", "fd", "len", "data"]);

        b.clear();
        let q = quat_enu_flu(0.0, 0.0, 0.0);
        tf_cdr(&mut b, &tf_head("base_link"), 1, 1_000_002, q);
        let m = &b[4..];
        assert_eq!(b.len(), 4 + 96);
        assert_eq!(m[..16], [1, 0, 0, 0, 1, 0, 0, 0, 0xd0, 0x07, 0, 0, 6, 0, 0, 0]);
        assert_eq!(&m[16..22], b"world\0");
        assert_eq!(m[24..28], [10, 0, 0, 0]);
        assert_eq!(&m[28..38], b"base_link\0");
        let f64at = |i: usize| f64::from_le_bytes(m[i..i + 8].try_into().unwrap());
        assert_eq!([40, 48, 56].map(f64at), [0.0; 3]);
        assert_eq!([64, 72, 80, 88].map(f64at), [q[1], q[2], q[3], q[0]]);
        let s = tf_message_schema();
        assert_eq!(fields(&s, None), [("geometry_msgs/TransformStamped[]".to_string(), "transforms".to_string())]);
        let names = |sec| fields(&s, Some(sec)).into_iter().map(|(_, n)| n).collect::<Vec<_>>();
        assert_eq!(names("geometry_msgs/TransformStamped"), ["header", "child_frame_id", "transform"]);
        assert_eq!(names("std_msgs/Header"), ["stamp", "frame_id"]);
        assert_eq!(names("geometry_msgs/Transform"), ["translation", "rotation"]);
        assert_eq!(names("geometry_msgs/Quaternion"), ["x", "y", "z", "w"]);

        let err = ros_sec(Topic::CanRx, (1u64 << 31) * 1_000_000).unwrap_err().to_string();
        assert!(err.contains("time past 2038 on /can/rx"), "{err}");
        let _: serde_json::Value = serde_json::from_str(&attitude_schema()).unwrap();
    }

    #[test]
    fn a_non_finite_value_or_a_time_past_2038_is_an_error_and_not_written() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("x.mcap");
        let mut f = McapFile::create(&p, false, false).unwrap();
        let mut e = est();
        f.estimate(&e).unwrap();
        e.bias[1] = f64::NAN;
        let err = f.estimate(&e).unwrap_err().to_string();
        assert!(err.contains("non-finite bias on /gyrocomp/estimate at t_us 1700000000123456"), "{err}");
        let mut e = est();
        e.t_us = 1 << 51;
        let err = f.estimate(&e).unwrap_err().to_string();
        assert!(err.contains("time past 2038 on /gyrocomp/estimate"), "{err}");
        drop(f);
        assert!(!p.exists(), "nothing committed");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0, "no temporary file left");
    }

    #[test]
    fn a_directory_or_a_missing_directory_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let e = McapFile::create(d.path(), false, false).err().unwrap().to_string();
        assert!(e.contains("is a directory"), "{e}");
        let e = McapFile::create(&d.path().join("no/such/x.mcap"), false, false).err().unwrap().to_string();
        assert!(e.contains("no/such") && e.contains("does not exist"), "{e}");
    }
}
