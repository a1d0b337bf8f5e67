//! ASAM MDF4 recordings through `falcon_mdf` (DESIGN.md: the crate that reads asammdf's
//! compressed files and angle masters).
//!
//! Reading: one channel group's time base makes one [`Recording`]. With a channel list, the
//! channels asked for (they must share a master); without, every channel of every group on the
//! same master as the first group with data (the others are named in `meta["skipped"]`). A time
//! master (sync type 1) becomes channel `t` [s] on a time basis; an angle master (sync type 2)
//! becomes `theta` [rad] on a crank-angle basis — MDF4 angle masters are in radians whatever
//! their unit label says (asammdf labels them "deg"; the label is kept in
//! `meta["master_unit_label"]`). Values are physical: the channel conversions are applied.
//! Uncompressed, deflate (DZ) and transposed-deflate data blocks are read.
//!
//! Writing: one group, every channel as float64, the time master from the recording's `t`
//! channel (MDF4 files carry a time master; a crank-angle recording keeps its angle in
//! `theta`, its `cycle` and `crank_deg` as ordinary channels). Optional deflate or
//! transposed-deflate compression.

use crate::IoError;
use falcon_mdf::blocks::channel::SyncType;
use falcon_mdf::write::WriteCodec;
use falcon_mdf::{Mf4File, Mf4Writer};
use physid_core::{Basis, Channel, Recording};
use std::path::Path;

/// Data-block compression when writing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MdfCompression {
    /// Plain data blocks.
    #[default]
    None,
    /// Deflate (`##DZ`, zip type 0).
    Deflate,
    /// Transposed deflate (zip type 1; asammdf's `compression=2`).
    TransposedDeflate,
}

fn mdf_err(path: &str, e: impl std::fmt::Display) -> IoError {
    IoError::Malformed {
        path: path.into(),
        detail: format!("MDF4: {e}"),
    }
}

/// Read an MDF4 file (module docs); `channels` selects channels by name (the master comes
/// with them).
pub fn read_mdf(path: impl AsRef<Path>, channels: Option<&[String]>) -> Result<Recording, IoError> {
    let p = path.as_ref().display().to_string();
    crate::contained(&p, "MDF4", || read_mdf_inner(path.as_ref(), &p, channels))
}

/// What a read takes from an MDF4 file: the channels chosen, their group and its master, and
/// the recording's basis and metadata (no channels yet).
struct Plan<'f> {
    chosen: Vec<&'f falcon_mdf::model::Channel>,
    group: (usize, usize),
    master: Option<&'f falcon_mdf::model::Channel>,
    /// The master's name and unit in the recording (`t` [s] or `theta` [rad]).
    axis: (&'static str, &'static str),
    rec: Recording,
}

impl<'f> Plan<'f> {
    fn of(file: &'f Mf4File, p: &str, channels: Option<&[String]>) -> Result<Self, IoError> {
        let data: Vec<&falcon_mdf::model::Channel> = file
            .channels()
            .filter(|c| !c.is_master() && c.is_numeric())
            .collect();
        let available = || {
            let mut v: Vec<&str> = data.iter().map(|c| c.name.as_str()).collect();
            v.sort_unstable();
            v.dedup();
            v.join(", ")
        };
        // The master is always read (as `t`, or `theta` for an angle master): asking for it
        // selects nothing more. `theta` on a time master is a data channel, and so is `t` on
        // an angle master when the file has one.
        let angle_master = file
            .channels()
            .any(|c| c.is_master() && matches!(c.sync_type, SyncType::Angle));
        let has_data = |n: &str| data.iter().any(|c| c.name == n);
        let is_master_name = |n: &str| {
            (n == "t" && !(angle_master && has_data("t")))
                || (n == "theta" && angle_master)
                || file.channels().any(|c| c.is_master() && c.name == n)
        };
        let chosen: Vec<&falcon_mdf::model::Channel> = match channels {
            Some(names) => names
                .iter()
                .filter(|n| !is_master_name(n))
                .map(|n| {
                    data.iter()
                        .copied()
                        .find(|c| &c.name == n)
                        .ok_or_else(|| IoError::Recording {
                            path: p.into(),
                            source: physid_core::RecordingError::MissingChannel {
                                name: n.clone(),
                                available: available(),
                            },
                        })
                })
                .collect::<Result<_, _>>()?,
            None => data.clone(),
        };
        let first = chosen.first().ok_or_else(|| IoError::Empty {
            path: p.into(),
            what: "no numeric channels",
        })?;
        let group = (first.data_group_index, first.channel_group_index);
        check_record_count(file, group, p)?;
        let master = file.master_channel(group.0, group.1);
        // An angle master, or physid's convention for its own time-master files: `cycle` and
        // `crank_deg` in the group (decided before a selection drops them).
        let in_group = |n: &str| {
            data.iter()
                .any(|c| c.name == n && (c.data_group_index, c.channel_group_index) == group)
        };
        let by_columns = in_group("cycle") && in_group("crank_deg");
        let mut rec = Recording::new(match master.map(|m| m.sync_type) {
            Some(SyncType::Angle) => Basis::CrankAngle,
            _ if by_columns => Basis::CrankAngle,
            _ => Basis::Time,
        });
        rec.meta.insert("source".into(), p.into());
        // The master's name by what it measures (a time master stays `t` on a crank-angle basis).
        let axis = match master.map(|m| m.sync_type) {
            Some(SyncType::Angle) => ("theta", "rad"),
            _ => ("t", "s"),
        };
        if let Some(m) = master {
            rec.meta.insert("master".into(), m.name.clone());
            rec.meta.insert("master_unit_label".into(), m.unit.clone());
        }
        Ok(Self {
            chosen,
            group,
            master,
            axis,
            rec,
        })
    }

    /// Whether every channel is in the master's group under a name of its own: then the read
    /// can go record block by record block ([`MdfChunks`]).
    fn streams(&self) -> bool {
        let mut names: Vec<&str> = vec![self.axis.0];
        self.chosen.iter().all(|c| {
            let fresh = !names.contains(&c.name.as_str());
            names.push(&c.name);
            fresh && (c.data_group_index, c.channel_group_index) == self.group
        })
    }
}

fn read_mdf_inner(path: &Path, p: &str, channels: Option<&[String]>) -> Result<Recording, IoError> {
    let file = Mf4File::open_buffered(path).map_err(|e| mdf_err(p, e))?;
    let plan = Plan::of(&file, p, channels)?;
    read_planned(&file, p, plan, channels.is_some())
}

/// The whole of a plan's channels; a channel of another group is taken when its time base is
/// the master's (else refused when asked for by name, skipped and named in `meta["skipped"]`
/// when reading everything).
fn read_planned(file: &Mf4File, p: &str, plan: Plan, asked: bool) -> Result<Recording, IoError> {
    let p = p.to_string();
    let Plan {
        chosen,
        group,
        axis: (mname, munit),
        mut rec,
        ..
    } = plan;
    let first = chosen[0];
    let axis = file.channel_timestamps(first).map_err(|e| mdf_err(&p, e))?;
    let mut skipped = Vec::new();
    let mut names_seen: Vec<String> = vec![mname.to_string()];
    let mut columns = vec![Channel {
        name: mname.into(),
        unit: munit.into(),
        values: axis.clone(),
    }];
    for c in &chosen {
        let same_group = (c.data_group_index, c.channel_group_index) == group;
        if !same_group {
            let other = file.channel_timestamps(c).map_err(|e| mdf_err(&p, e))?;
            if other != axis {
                if asked {
                    return Err(IoError::Malformed {
                        path: p,
                        detail: format!(
                            "channels '{}' and '{}' are on different time bases ({} and {} samples): read them separately",
                            first.name,
                            c.name,
                            axis.len(),
                            other.len()
                        ),
                    });
                }
                skipped.push(c.name.clone());
                continue;
            }
        }
        if names_seen.contains(&c.name) {
            skipped.push(format!("{} (duplicate name)", c.name));
            continue;
        }
        let values = file
            .signal(c)
            .and_then(|s| s.values_f64())
            .map_err(|e| mdf_err(&p, format!("channel '{}': {e}", c.name)))?;
        names_seen.push(c.name.clone());
        columns.push(Channel {
            name: c.name.clone(),
            unit: c.unit.clone(),
            values,
        });
    }
    if !skipped.is_empty() {
        rec.meta.insert("skipped".into(), skipped.join(", "));
    }
    for ch in columns {
        rec.push(ch).map_err(|source| IoError::Recording {
            path: p.clone(),
            source,
        })?;
    }
    Ok(rec)
}

/// What the reading thread of [`MdfChunks`] sends.
enum MdfMsg {
    /// The recording's channels (no samples), basis and metadata; the records claimed.
    Header(Recording, u64),
    Columns(Vec<Vec<f64>>),
    Failed(IoError),
    End,
}

/// An MDF4 file read a window of records at a time (`falcon_mdf`'s `signals_chunks`) on a
/// thread of its own, which owns the file and hands over at most one chunk ahead: memory is
/// bounded by two chunks. The values are those [`read_mdf`] reads (the same channels, the
/// master validated window by window). A selection spanning channel groups, or a file whose
/// channels cannot all go by the first group's master, is read whole and handed out in
/// chunks (memory proportional to those channels).
pub struct MdfChunks {
    pub(crate) p: String,
    rx: std::sync::mpsc::Receiver<MdfMsg>,
    header: Recording,
    claimed: u64,
    done: bool,
}

impl MdfChunks {
    /// Open `path` and read its blocks' metadata; `channels`: the channels to read (the master
    /// comes first, as `t` or `theta`), all on the first group's master if `None`.
    pub fn open(path: impl AsRef<Path>, channels: Option<&[String]>) -> Result<Self, IoError> {
        let path = path.as_ref().to_path_buf();
        let p = path.display().to_string();
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let channels = channels.map(<[String]>::to_vec);
        let q = p.clone();
        std::thread::Builder::new()
            .name("physid-mdf-reader".into())
            .spawn(move || {
                let r =
                    crate::contained(&q, "MDF4", || produce(&path, &q, channels.as_deref(), &tx));
                let _ = tx.send(match r {
                    Ok(()) => MdfMsg::End,
                    Err(e) => MdfMsg::Failed(e),
                });
            })
            .map_err(|source| IoError::Os {
                path: p.clone(),
                source,
            })?;
        match rx.recv() {
            Ok(MdfMsg::Header(header, claimed)) => Ok(Self {
                p,
                rx,
                header,
                claimed,
                done: false,
            }),
            Ok(MdfMsg::Failed(e)) => Err(e),
            _ => Err(mdf_err(&p, "the reader stopped before the file's header")),
        }
    }

    /// The channels (no samples), basis and metadata.
    pub fn header(&self) -> &Recording {
        &self.header
    }

    /// The records the channel group claims.
    pub fn claimed_rows(&self) -> u64 {
        self.claimed
    }

    /// The next window of every channel, in the header's order (`None` after the last).
    pub fn next_columns(&mut self) -> Result<Option<Vec<Vec<f64>>>, IoError> {
        if self.done {
            return Ok(None);
        }
        match self.rx.recv() {
            Ok(MdfMsg::Columns(c)) => Ok(Some(c)),
            Ok(MdfMsg::Failed(e)) => {
                self.done = true;
                Err(e)
            }
            Ok(MdfMsg::End) => {
                self.done = true;
                Ok(None)
            }
            Ok(MdfMsg::Header(..)) | Err(_) => {
                self.done = true;
                Err(mdf_err(&self.p, "the reader stopped"))
            }
        }
    }
}

/// The reading thread: the header, then the windows, each sent when the reader has taken the
/// one before. A reader gone away (dropped) ends it.
fn produce(
    path: &Path,
    p: &str,
    channels: Option<&[String]>,
    tx: &std::sync::mpsc::SyncSender<MdfMsg>,
) -> Result<(), IoError> {
    let file = Mf4File::open_buffered(path).map_err(|e| mdf_err(p, e))?;
    let plan = Plan::of(&file, p, channels)?;
    let header_of = |rec: &Recording| {
        let mut h = Recording::new(rec.basis);
        h.meta = rec.meta.clone();
        for c in rec.channels() {
            let _ = h.push(Channel {
                name: c.name.clone(),
                unit: c.unit.clone(),
                values: Vec::new(),
            });
        }
        h
    };
    if !plan.streams() {
        let rec = read_planned(&file, p, plan, channels.is_some())?;
        if tx
            .send(MdfMsg::Header(header_of(&rec), rec.len() as u64))
            .is_err()
        {
            return Ok(());
        }
        for start in (0..rec.len()).step_by(crate::format::CHUNK_ROWS) {
            let part = rec.slice(start..start + crate::format::CHUNK_ROWS);
            let cols = part.channels().iter().map(|c| c.values.clone()).collect();
            if tx.send(MdfMsg::Columns(cols)).is_err() {
                return Ok(());
            }
        }
        return Ok(());
    }
    let (dg, cg) = plan.group;
    let claimed = file.data_groups()[dg].channel_groups[cg].sample_count;
    let mut header = plan.rec.clone();
    let mut list: Vec<falcon_mdf::model::Channel> = Vec::new();
    let _ = header.push(Channel {
        name: plan.axis.0.into(),
        unit: plan.axis.1.into(),
        values: Vec::new(),
    });
    if let Some(m) = plan.master {
        list.push(m.clone());
    }
    for c in &plan.chosen {
        let _ = header.push(Channel {
            name: c.name.clone(),
            unit: c.unit.clone(),
            values: Vec::new(),
        });
        list.push((*c).clone());
    }
    if tx.send(MdfMsg::Header(header, claimed)).is_err() {
        return Ok(());
    }
    let windows = file
        .signals_chunks(&list, crate::format::CHUNK_ROWS)
        .map_err(|e| mdf_err(p, e))?;
    let (mut offset, mut previous) = (0usize, None);
    for window in windows {
        let signals = window.map_err(|e| mdf_err(p, e))?;
        let mut cols = Vec::with_capacity(plan.chosen.len() + 1);
        for s in &signals {
            cols.push(
                s.values_f64()
                    .map_err(|e| mdf_err(p, format!("channel '{}': {e}", s.channel().name)))?,
            );
        }
        let n = cols.first().map_or(0, Vec::len);
        match plan.master {
            Some(m) => {
                falcon_mdf::time_ops::validate_master_axis(
                    &m.name,
                    &cols[0],
                    signals[0].validity().as_deref(),
                    offset,
                    previous,
                )
                .map_err(|e| mdf_err(p, e))?;
                previous = cols[0].last().copied().or(previous);
            }
            // No master: the sample index, as `channel_timestamps` gives it.
            None => cols.insert(0, (offset..offset + n).map(|i| i as f64).collect()),
        }
        offset += n;
        if tx.send(MdfMsg::Columns(cols)).is_err() {
            return Ok(());
        }
    }
    Ok(())
}

/// A sorted data group's record count against its data blocks' length: a count corrupted
/// smaller would otherwise read as a shorter recording, silently.
fn check_record_count(file: &Mf4File, (dg, cg): (usize, usize), p: &str) -> Result<(), IoError> {
    let Some(d) = file.data_groups().get(dg) else {
        return Ok(());
    };
    if d.is_unsorted() || d.channel_groups.len() != 1 {
        return Ok(());
    }
    let Some(g) = d.channel_groups.get(cg) else {
        return Ok(());
    };
    let record = g.record_size(d.rec_id_size()) as u64;
    let held = d.block_index().total_size();
    if record > 0 && held / record > g.sample_count {
        return Err(IoError::Malformed {
            path: p.into(),
            detail: format!(
                "corrupt MDF4: channel group {cg} of data group {dg} claims {} records, but its data blocks hold {} ({held} bytes of {record}-byte records)",
                g.sample_count,
                held / record
            ),
        });
    }
    Ok(())
}

/// Write a recording as MDF4 (module docs). `start_time_ns`: the file's start time in
/// nanoseconds since the Unix epoch (fixed for reproducible files; `None`: now).
pub fn write_mdf(
    path: impl AsRef<Path>,
    rec: &Recording,
    compression: MdfCompression,
    start_time_ns: Option<i64>,
) -> Result<(), IoError> {
    let p = path.as_ref().display().to_string();
    let t = rec.values("t").map_err(|_| IoError::Malformed {
        path: p.clone(),
        detail: "MDF4 files carry a time master: the recording needs a 't' channel [s]".into(),
    })?;
    // MDF4 orders a group's records by its time master (and the writer sorts them): a time
    // that goes back or is not a number would reorder or lose samples, so it is refused.
    if let Some(i) = t.iter().position(|v| !v.is_finite()) {
        return Err(IoError::Malformed {
            path: p,
            detail: format!("MDF4 needs a finite time master: 't' is {} at sample {i}; write CSV or Parquet to keep the samples as they are", t[i]),
        });
    }
    if let Some(i) = t.windows(2).position(|w| w[1] < w[0]) {
        return Err(IoError::Malformed {
            path: p,
            detail: format!("MDF4 orders records by their time master, and 't' goes back at sample {}: write CSV or Parquet to keep the samples in their order", i + 1),
        });
    }
    let mut w = match start_time_ns {
        Some(ns) => Mf4Writer::with_start_time_ns(ns),
        None => Mf4Writer::new(),
    };
    match compression {
        MdfCompression::None => {}
        MdfCompression::Deflate => {
            w.set_compression(true);
            w.set_codec(WriteCodec::Deflate);
        }
        MdfCompression::TransposedDeflate => {
            w.set_compression(true);
            w.set_codec(WriteCodec::TransposedDeflate);
        }
    }
    let g = w.add_group(t).map_err(|e| mdf_err(&p, e))?;
    for ch in rec.channels().iter().filter(|c| c.name != "t") {
        g.add_channel(&ch.name, &ch.unit, &ch.values)
            .map_err(|e| mdf_err(&p, format!("channel '{}': {e}", ch.name)))?;
    }
    w.write_to_file(path.as_ref()).map_err(|e| mdf_err(&p, e))
}

/// An MDF4 file written as the samples arrive (the live service's log): one group, every
/// channel as float64 after the time master, in one uncompressed data block that grows at the
/// end of the file. The blocks before it are `falcon_mdf`'s own for a group with no samples
/// yet; each chunk appends its records, and [`close`](Self::close) writes the block's length
/// and the group's record count into them. Memory stays one record, however long it records,
/// and the file is byte for byte what [`write_mdf`] writes for the same recording uncompressed.
pub struct MdfWriter {
    path: String,
    names: Vec<String>,
    out: std::io::BufWriter<std::fs::File>,
    header_len: u64,
    /// Where the data block starts, and where the group's record count is.
    dt_off: u64,
    cycle_count_off: u64,
    record: Vec<u8>,
    rows: usize,
    last_t: f64,
}

/// A little-endian u64 at `at` of `b`.
fn u64_at(b: &[u8], at: u64) -> Option<u64> {
    let at = usize::try_from(at).ok()?;
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

impl MdfWriter {
    /// Create `path` for recordings with `like`'s channels (which must include the time `t`
    /// [s]) and units; `start_time_ns` as [`write_mdf`]'s.
    pub fn create(
        path: impl AsRef<Path>,
        like: &Recording,
        start_time_ns: Option<i64>,
    ) -> Result<Self, IoError> {
        let p = path.as_ref().display().to_string();
        if like.channel("t").is_err() {
            return Err(IoError::Malformed {
                path: p,
                detail: "MDF4 files carry a time master: the recording needs a 't' channel [s]"
                    .into(),
            });
        }
        let mut w = match start_time_ns {
            Some(ns) => Mf4Writer::with_start_time_ns(ns),
            None => Mf4Writer::new(),
        };
        let g = w.add_group(&[]).map_err(|e| mdf_err(&p, e))?;
        let names: Vec<String> = like
            .channels()
            .iter()
            .filter(|c| c.name != "t")
            .map(|c| c.name.clone())
            .collect();
        for ch in like.channels().iter().filter(|c| c.name != "t") {
            g.add_channel(&ch.name, &ch.unit, &[])
                .map_err(|e| mdf_err(&p, format!("channel '{}': {e}", ch.name)))?;
        }
        let mut header = Vec::new();
        w.write(&mut header).map_err(|e| mdf_err(&p, e))?;
        // Find the data block and the record count: HD (at 64) → its first DG → the DG's first
        // CG and its data block, which must be the file's last block, still empty.
        let bad = |what: &str| {
            mdf_err(
                &p,
                format!("unexpected block layout from falcon_mdf: {what}"),
            )
        };
        let id = |at: u64| {
            usize::try_from(at)
                .ok()
                .and_then(|a| header.get(a..a + 4))
                .map(|s| s.to_vec())
        };
        let dg = u64_at(&header, 64 + 24).ok_or_else(|| bad("no HD"))?;
        let cg = u64_at(&header, dg + 32).ok_or_else(|| bad("no DG"))?;
        let dt_off = u64_at(&header, dg + 40).ok_or_else(|| bad("no DG data link"))?;
        let links = u64_at(&header, cg + 16).ok_or_else(|| bad("no CG"))?;
        let cycle_count_off = cg + 24 + 8 * links + 8;
        let data_bytes_off = usize::try_from(cycle_count_off + 16).map_err(|_| bad("CG"))?;
        let data_bytes = header
            .get(data_bytes_off..data_bytes_off + 4)
            .and_then(|b| b.try_into().ok())
            .map(u32::from_le_bytes)
            .ok_or_else(|| bad("CG record size"))?;
        let record_len = 8 * (names.len() + 1);
        if id(dg).as_deref() != Some(b"##DG")
            || id(cg).as_deref() != Some(b"##CG")
            || id(dt_off).as_deref() != Some(b"##DT")
            || dt_off + 24 != header.len() as u64
            || data_bytes as usize != record_len
        {
            return Err(bad("not one empty DT block of float64 records at the end"));
        }
        let file = std::fs::File::create(path.as_ref()).map_err(|source| IoError::Os {
            path: p.clone(),
            source,
        })?;
        let mut out = std::io::BufWriter::new(file);
        std::io::Write::write_all(&mut out, &header).map_err(|source| IoError::Os {
            path: p.clone(),
            source,
        })?;
        Ok(Self {
            path: p,
            names,
            out,
            header_len: header.len() as u64,
            dt_off,
            cycle_count_off,
            record: Vec::with_capacity(record_len),
            rows: 0,
            last_t: f64::NEG_INFINITY,
        })
    }

    /// Append `rec`'s samples (the file's channels; its time must go on forward and be finite).
    pub fn append(&mut self, rec: &Recording) -> Result<(), IoError> {
        let bad = |detail: String| IoError::Malformed {
            path: self.path.clone(),
            detail,
        };
        let t = rec
            .values("t")
            .map_err(|_| bad("appending samples without 't'".into()))?;
        let cols = self
            .names
            .iter()
            .map(|n| rec.values(n))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| bad(format!("appending to an MDF4 log: {e}")))?;
        if rec.channels().len() != self.names.len() + 1 {
            return Err(bad(format!(
                "appending {} channels to a file of {}",
                rec.channels().len(),
                self.names.len() + 1
            )));
        }
        let mut last = self.last_t;
        for (i, &ti) in t.iter().enumerate() {
            if !(ti.is_finite() && ti >= last) {
                return Err(bad(format!(
                    "MDF4 orders records by their time master: 't' is {ti} after {last} (sample {i} of the chunk)"
                )));
            }
            last = ti;
        }
        for i in 0..t.len() {
            self.record.clear();
            self.record.extend_from_slice(&t[i].to_le_bytes());
            for c in &cols {
                self.record.extend_from_slice(&c[i].to_le_bytes());
            }
            std::io::Write::write_all(&mut self.out, &self.record).map_err(|source| {
                IoError::Os {
                    path: self.path.clone(),
                    source,
                }
            })?;
        }
        self.last_t = last;
        self.rows += t.len();
        Ok(())
    }

    /// Samples written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Bytes in the file so far (written and buffered).
    pub fn bytes(&self) -> usize {
        (self.header_len + (self.rows * 8 * (self.names.len() + 1)) as u64) as usize
    }

    /// Finish the file: the data block's length and the record count.
    pub fn close(self) -> Result<(), IoError> {
        use std::io::{Seek, SeekFrom, Write};
        let Self {
            path,
            names,
            out,
            dt_off,
            cycle_count_off,
            rows,
            ..
        } = self;
        let os = |source| IoError::Os {
            path: path.clone(),
            source,
        };
        let mut file = out.into_inner().map_err(|e| os(e.into_error()))?;
        let dt_len = 24 + (rows * 8 * (names.len() + 1)) as u64;
        file.seek(SeekFrom::Start(dt_off + 8)).map_err(os)?;
        file.write_all(&dt_len.to_le_bytes()).map_err(os)?;
        file.seek(SeekFrom::Start(cycle_count_off)).map_err(os)?;
        file.write_all(&(rows as u64).to_le_bytes()).map_err(os)?;
        file.sync_all().map_err(os)
    }
}
