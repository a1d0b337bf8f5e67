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
//! transposed-deflate compression: [`write_mdf`] (`falcon_mdf`) deflates a whole recording into
//! one `##DZ` block; [`MdfWriter`] writes as the samples come, in blocks of at most
//! [`MDF_BLOCK_BYTES`] of records each deflated into a `##DZ`, listed at the end by a
//! `##HL`/`##DL` pair.

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
                        detail: different_bases(&first.name, &c.name, axis.len(), other.len()),
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
/// master validated window by window). Channels of several groups on one time base are read
/// side by side, a window of each group at a time ([`Layout`]); only when the first group has
/// no master to compare the others' times with are they read whole and handed out in chunks.
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

/// The cycle count channel group `cg` of data group `dg` declares, as written in the file
/// (the MDF crate takes the data's record count instead, so a count the data do not bear out
/// would pass unseen): HD → its first DG (link 0 at 64 + 24) → the next DGs (link 0) → the
/// DG's first CG (link 1) → the next CGs (link 0); the count follows the CG's links and its
/// record id. `None` where the chain cannot be followed.
fn declared_cycles(path: &Path, dg: usize, cg: usize) -> Option<u64> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path).ok()?;
    let mut at = |off: u64| -> Option<u64> {
        let mut b = [0u8; 8];
        f.seek(SeekFrom::Start(off)).ok()?;
        f.read_exact(&mut b).ok()?;
        Some(u64::from_le_bytes(b)).filter(|&v| v != 0)
    };
    let mut d = at(64 + 24)?;
    for _ in 0..dg {
        d = at(d + 24)?;
    }
    let mut c = at(d + 32)?;
    for _ in 0..cg {
        c = at(c + 24)?;
    }
    let links = at(c + 16).filter(|&n| n < 64)?;
    let count_at = c + 24 + 8 * links + 8;
    let mut b = [0u8; 8];
    f.seek(SeekFrom::Start(count_at)).ok()?;
    f.read_exact(&mut b).ok()?;
    Some(u64::from_le_bytes(b))
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
    let Some(layout) = Layout::of(&file, p, &plan, channels.is_some())? else {
        // Channels of another group while the first has no master: read whole.
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
    };
    let (dg, cg) = plan.group;
    // The records there are; a cycle count the group declares otherwise is the claim (the
    // reader then says the two differ, and a whole read checks the claim against memory).
    let records = file.data_groups()[dg].channel_groups[cg].sample_count;
    let claimed = declared_cycles(path, dg, cg).unwrap_or(records);
    let mut header = plan.rec.clone();
    if !layout.skipped.is_empty() {
        header
            .meta
            .insert("skipped".into(), layout.skipped.join(", "));
    }
    let _ = header.push(Channel {
        name: plan.axis.0.into(),
        unit: plan.axis.1.into(),
        values: Vec::new(),
    });
    for &(k, j) in &layout.columns {
        let c = &layout.lists[k][j];
        let _ = header.push(Channel {
            name: c.name.clone(),
            unit: c.unit.clone(),
            values: Vec::new(),
        });
    }
    if tx.send(MdfMsg::Header(header, claimed)).is_err() {
        return Ok(());
    }
    // The groups side by side, a window of the same records of each.
    let mut windows = layout
        .lists
        .iter()
        .map(|l| file.signals_chunks(l, crate::format::CHUNK_ROWS))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| mdf_err(p, e))?;
    let (mut offset, mut previous) = (0usize, None);
    loop {
        let mut signals = Vec::with_capacity(windows.len());
        for w in &mut windows {
            signals.push(w.next().transpose().map_err(|e| mdf_err(p, e))?);
        }
        let signals = match signals.iter().filter(|s| s.is_some()).count() {
            0 => break,
            n if n == signals.len() => signals.into_iter().flatten().collect::<Vec<_>>(),
            _ => {
                return Err(mdf_err(
                    p,
                    "channel groups on one time base ended at different records",
                ))
            }
        };
        let values = |k: usize, j: usize| {
            let s = &signals[k][j];
            s.values_f64()
                .map_err(|e| mdf_err(p, format!("channel '{}': {e}", s.channel().name)))
        };
        let mut cols = Vec::with_capacity(layout.columns.len() + 1);
        cols.push(Vec::new());
        for &(k, j) in &layout.columns {
            cols.push(values(k, j)?);
        }
        cols[0] = match plan.master {
            Some(m) => {
                let t = values(0, 0)?;
                falcon_mdf::time_ops::validate_master_axis(
                    &m.name,
                    &t,
                    signals[0][0].validity().as_deref(),
                    offset,
                    previous,
                )
                .map_err(|e| mdf_err(p, e))?;
                previous = t.last().copied().or(previous);
                t
            }
            // No master: the sample index, as `channel_timestamps` gives it.
            None => {
                let n = cols.get(1).map_or(0, Vec::len);
                (offset..offset + n).map(|i| i as f64).collect()
            }
        };
        let n = cols[0].len();
        if cols.iter().any(|c| c.len() != n) {
            return Err(mdf_err(
                p,
                "channel groups on one time base hold windows of different lengths",
            ));
        }
        offset += n;
        if tx.send(MdfMsg::Columns(cols)).is_err() {
            return Ok(());
        }
    }
    Ok(())
}

/// How a read goes window by window: the groups read side by side — the master's first, led by
/// the master — and where each of the recording's channels comes from. A channel of another
/// group is taken when that group's time base is the master's (as many records, the same
/// times: compared window by window before reading), as [`read_planned`] takes it; a name seen
/// already is skipped.
struct Layout {
    /// Per group, the channels read from it.
    lists: Vec<Vec<falcon_mdf::model::Channel>>,
    /// The recording's channels after the master: (group, place in its list).
    columns: Vec<(usize, usize)>,
    /// What was left out, for `meta["skipped"]`.
    skipped: Vec<String>,
}

impl Layout {
    /// The layout of `plan`, or `None` when it takes channels of another group and the first
    /// has no master to compare times by.
    fn of(file: &Mf4File, p: &str, plan: &Plan, asked: bool) -> Result<Option<Self>, IoError> {
        let count =
            |(dg, cg): (usize, usize)| file.data_groups()[dg].channel_groups[cg].sample_count;
        let first = plan.chosen[0];
        let mut groups = vec![plan.group];
        let mut lists = vec![plan.master.map(|m| vec![m.clone()]).unwrap_or_default()];
        let (mut columns, mut skipped) = (Vec::new(), Vec::new());
        let mut names_seen: Vec<&str> = vec![plan.axis.0];
        let mut bases: Vec<((usize, usize), bool)> = Vec::new();
        for c in &plan.chosen {
            let g = (c.data_group_index, c.channel_group_index);
            if g != plan.group {
                let same = match bases.iter().find(|(h, _)| *h == g) {
                    Some(&(_, same)) => same,
                    None => {
                        let (Some(m), Some(other)) = (plan.master, file.master_channel(g.0, g.1))
                        else {
                            return Ok(None);
                        };
                        let same = count(g) == count(plan.group) && same_times(file, p, m, other)?;
                        bases.push((g, same));
                        same
                    }
                };
                if !same {
                    if asked {
                        return Err(IoError::Malformed {
                            path: p.into(),
                            detail: different_bases(
                                &first.name,
                                &c.name,
                                count(plan.group) as usize,
                                count(g) as usize,
                            ),
                        });
                    }
                    skipped.push(c.name.clone());
                    continue;
                }
            }
            if names_seen.contains(&c.name.as_str()) {
                skipped.push(format!("{} (duplicate name)", c.name));
                continue;
            }
            names_seen.push(&c.name);
            let k = match groups.iter().position(|h| *h == g) {
                Some(k) => k,
                None => {
                    groups.push(g);
                    lists.push(Vec::new());
                    lists.len() - 1
                }
            };
            lists[k].push((*c).clone());
            columns.push((k, lists[k].len() - 1));
        }
        Ok(Some(Self {
            lists,
            columns,
            skipped,
        }))
    }
}

/// Channels `a` and `b` asked for together, on time bases of `na` and `nb` samples that differ.
fn different_bases(a: &str, b: &str, na: usize, nb: usize) -> String {
    let how = if na == nb {
        format!("{na} samples each, at different times")
    } else {
        format!("{na} and {nb} samples")
    };
    format!("channels '{a}' and '{b}' are on different time bases ({how}): read them separately")
}

/// Whether two masters hold the same times, compared a window at a time (the other validated
/// as [`Mf4File::channel_timestamps`] validates it).
fn same_times(
    file: &Mf4File,
    p: &str,
    master: &falcon_mdf::model::Channel,
    other: &falcon_mdf::model::Channel,
) -> Result<bool, IoError> {
    let err = |e| mdf_err(p, e);
    let a = file
        .signals_chunks(&[master], crate::format::CHUNK_ROWS)
        .map_err(err)?;
    let b = file
        .signals_chunks(&[other], crate::format::CHUNK_ROWS)
        .map_err(err)?;
    let (mut offset, mut previous) = (0usize, None);
    for (x, y) in a.zip(b) {
        let (x, y) = (x.map_err(err)?, y.map_err(err)?);
        let (tx, ty) = (
            x[0].values_f64().map_err(err)?,
            y[0].values_f64().map_err(err)?,
        );
        falcon_mdf::time_ops::validate_master_axis(
            &other.name,
            &ty,
            y[0].validity().as_deref(),
            offset,
            previous,
        )
        .map_err(err)?;
        previous = ty.last().copied().or(previous);
        offset += ty.len();
        if tx != ty {
            return Ok(false);
        }
    }
    Ok(true)
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

/// The most record bytes [`MdfWriter`] deflates into one `##DZ` block: 4 MiB, the size the
/// MDF 4.1 standard recommends a compressed block's original data not exceed.
pub const MDF_BLOCK_BYTES: usize = 4 << 20;

/// An MDF4 file written as the samples arrive (the live service's log, `convert`'s output):
/// one group, every channel as float64 after the time master. The blocks before the data are
/// `falcon_mdf`'s own for a group with no samples yet; [`close`](Self::close) writes the
/// group's record count into them.
///
/// - Uncompressed ([`create`](Self::create)): one data block that grows at the end of the
///   file, its length written at the close. Memory stays one record, however long it records,
///   and the file is byte for byte what [`write_mdf`] writes for the same recording.
/// - Compressed ([`create_compressed`](Self::create_compressed)): the records gathered into
///   blocks of at most `block_bytes`, each deflated (transposed first for
///   [`MdfCompression::TransposedDeflate`], MDF4 zip type 1) into a `##DZ` as it fills; the
///   close lists them in a `##DL` (equal length: every block but the last holds as many
///   records) behind a `##HL` that names the zip type, and links the group to it. Memory stays
///   about three blocks.
pub struct MdfWriter {
    path: String,
    names: Vec<String>,
    out: std::io::BufWriter<std::fs::File>,
    header_len: u64,
    /// Where the data block starts, where the group links to it, and where the group's record
    /// count is.
    dt_off: u64,
    dg_data_link_off: u64,
    cycle_count_off: u64,
    record: Vec<u8>,
    rows: usize,
    last_t: f64,
    zip: Option<Zip>,
}

/// The compressed blocks of an [`MdfWriter`].
struct Zip {
    transposed: bool,
    /// Records gathered for the next block, at most `block_bytes`.
    block: Vec<u8>,
    block_bytes: usize,
    /// The deflated stream of the last block written (its buffer kept).
    packed: Vec<u8>,
    /// Where the next block starts in the file.
    at: u64,
    /// Where each block starts, and the last one's original length.
    blocks: Vec<u64>,
    last_len: u64,
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
        Self::create_compressed(path, like, start_time_ns, MdfCompression::None, 0)
    }

    /// Create `path` as [`create`](Self::create) does, its records compressed by `compression`
    /// in blocks of at most `block_bytes` ([`MDF_BLOCK_BYTES`]; at least one record).
    pub fn create_compressed(
        path: impl AsRef<Path>,
        like: &Recording,
        start_time_ns: Option<i64>,
        compression: MdfCompression,
        block_bytes: usize,
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
        // Compressed, the empty data block is left out: the blocks go in its place.
        let zip = (compression != MdfCompression::None).then(|| Zip {
            transposed: compression == MdfCompression::TransposedDeflate,
            block: Vec::new(),
            block_bytes: block_bytes.max(record_len) / record_len * record_len,
            packed: Vec::new(),
            at: dt_off,
            blocks: Vec::new(),
            last_len: 0,
        });
        let kept = if zip.is_some() {
            &header[..dt_off as usize]
        } else {
            &header[..]
        };
        std::io::Write::write_all(&mut out, kept).map_err(|source| IoError::Os {
            path: p.clone(),
            source,
        })?;
        Ok(Self {
            path: p,
            names,
            out,
            header_len: header.len() as u64,
            dt_off,
            dg_data_link_off: dg + 40,
            cycle_count_off,
            record: Vec::with_capacity(record_len),
            rows: 0,
            last_t: f64::NEG_INFINITY,
            zip,
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
            match &mut self.zip {
                None => {
                    std::io::Write::write_all(&mut self.out, &self.record).map_err(|source| {
                        IoError::Os {
                            path: self.path.clone(),
                            source,
                        }
                    })?
                }
                Some(z) => {
                    z.block.extend_from_slice(&self.record);
                    if z.block.len() >= z.block_bytes {
                        z.flush(&mut self.out, self.record.len())
                            .map_err(|e| mdf_err(&self.path, e))?;
                    }
                }
            }
        }
        self.last_t = last;
        self.rows += t.len();
        Ok(())
    }

    /// Make every sample appended so far survive a crash (uncompressed files): the records
    /// are written and on the disk, then the data block's length and the record count say so
    /// — in that order, so the file never claims a record it does not hold, and a reader
    /// (asammdf, physid) of a file whose writer was killed reads every sample committed. A
    /// compressed file lists its blocks only when closed: it is flushed, not made readable.
    pub fn commit(&mut self) -> Result<(), IoError> {
        use std::io::{Seek, SeekFrom, Write};
        let os = |source| IoError::Os {
            path: self.path.clone(),
            source,
        };
        self.out.flush().map_err(os)?;
        if self.zip.is_some() {
            return Ok(());
        }
        let mut f = self.out.get_ref();
        f.sync_data().map_err(os)?;
        let dt_len = 24 + (self.rows * 8 * (self.names.len() + 1)) as u64;
        f.seek(SeekFrom::Start(self.dt_off + 8)).map_err(os)?;
        f.write_all(&dt_len.to_le_bytes()).map_err(os)?;
        f.seek(SeekFrom::Start(self.cycle_count_off)).map_err(os)?;
        f.write_all(&(self.rows as u64).to_le_bytes()).map_err(os)?;
        f.seek(SeekFrom::End(0)).map_err(os)?;
        Ok(())
    }

    /// Samples written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Bytes in the file so far (written and buffered; compressed: the records not yet
    /// deflated as they are).
    pub fn bytes(&self) -> usize {
        match &self.zip {
            None => (self.header_len + (self.rows * 8 * (self.names.len() + 1)) as u64) as usize,
            Some(z) => z.at as usize + z.block.len(),
        }
    }

    /// Finish the file: the data block's length and the record count.
    pub fn close(self) -> Result<(), IoError> {
        use std::io::{Seek, SeekFrom, Write};
        let Self {
            path,
            names,
            mut out,
            dt_off,
            dg_data_link_off,
            cycle_count_off,
            rows,
            zip,
            ..
        } = self;
        let os = |source| IoError::Os {
            path: path.clone(),
            source,
        };
        // Compressed: the last block, then the list of them; the group links to the list.
        let data_link = match zip {
            Some(mut z) => {
                let record_len = 8 * (names.len() + 1);
                z.flush(&mut out, record_len)
                    .map_err(|e| mdf_err(&path, e))?;
                z.list(&mut out).map_err(os)?
            }
            None => None,
        };
        let mut file = out.into_inner().map_err(|e| os(e.into_error()))?;
        match data_link {
            Some(hl) => {
                file.seek(SeekFrom::Start(dg_data_link_off)).map_err(os)?;
                file.write_all(&hl.to_le_bytes()).map_err(os)?;
            }
            None => {
                let dt_len = 24 + (rows * 8 * (names.len() + 1)) as u64;
                file.seek(SeekFrom::Start(dt_off + 8)).map_err(os)?;
                file.write_all(&dt_len.to_le_bytes()).map_err(os)?;
            }
        }
        file.seek(SeekFrom::Start(cycle_count_off)).map_err(os)?;
        file.write_all(&(rows as u64).to_le_bytes()).map_err(os)?;
        file.sync_all().map_err(os)
    }
}

/// An MDF4 block's header: its id, reserved bytes, length and link count.
fn block_header(buf: &mut Vec<u8>, id: &[u8; 4], length: u64, links: u64) {
    buf.extend_from_slice(id);
    buf.extend_from_slice(&[0u8; 4]);
    buf.extend_from_slice(&length.to_le_bytes());
    buf.extend_from_slice(&links.to_le_bytes());
}

impl Zip {
    /// Deflate the records gathered (if any) into a `##DZ` at the end of the file.
    fn flush(
        &mut self,
        out: &mut impl std::io::Write,
        record_len: usize,
    ) -> Result<(), std::io::Error> {
        if self.block.is_empty() {
            return Ok(());
        }
        let transposed;
        let data = if self.transposed {
            transposed = falcon_mdf::write::transpose(&self.block, record_len);
            &transposed[..]
        } else {
            &self.block[..]
        };
        let mut packed = std::mem::take(&mut self.packed);
        packed.clear();
        let mut z = flate2::write::ZlibEncoder::new(packed, flate2::Compression::default());
        std::io::Write::write_all(&mut z, data)?;
        self.packed = z.finish()?;
        let mut head = Vec::with_capacity(48);
        block_header(&mut head, b"##DZ", 48 + self.packed.len() as u64, 0);
        head.extend_from_slice(b"DT");
        head.push(u8::from(self.transposed)); // dz_zip_type: 0 deflate, 1 transposed
        head.push(0);
        let parameter = if self.transposed {
            record_len as u32
        } else {
            0
        };
        head.extend_from_slice(&parameter.to_le_bytes());
        head.extend_from_slice(&(self.block.len() as u64).to_le_bytes());
        head.extend_from_slice(&(self.packed.len() as u64).to_le_bytes());
        out.write_all(&head)?;
        out.write_all(&self.packed)?;
        self.blocks.push(self.at);
        self.last_len = self.block.len() as u64;
        self.at += head.len() as u64 + self.packed.len() as u64;
        self.block.clear();
        Ok(())
    }

    /// The `##DL` listing the blocks and the `##HL` in front of it, at the end of the file:
    /// where the `##HL` is, or `None` when no record was written (then an empty `##DT`
    /// stands where the blocks would).
    fn list(&self, out: &mut impl std::io::Write) -> Result<Option<u64>, std::io::Error> {
        let mut buf = Vec::new();
        if self.blocks.is_empty() {
            block_header(&mut buf, b"##DT", 24, 0);
            out.write_all(&buf)?;
            return Ok(None);
        }
        let n = self.blocks.len() as u64;
        let dl_len = 24 + 8 * (n + 1) + 16;
        block_header(&mut buf, b"##DL", dl_len, n + 1);
        buf.extend_from_slice(&0u64.to_le_bytes()); // dl_dl_next
        for b in &self.blocks {
            buf.extend_from_slice(&b.to_le_bytes());
        }
        buf.push(0x01); // dl_flags: equal length
        buf.extend_from_slice(&[0u8; 3]);
        buf.extend_from_slice(&(n as u32).to_le_bytes());
        // Every block but the last holds a full block; one block: its own length.
        let equal = if n == 1 {
            self.last_len
        } else {
            self.block_bytes as u64
        };
        buf.extend_from_slice(&equal.to_le_bytes());
        let hl = self.at + dl_len;
        block_header(&mut buf, b"##HL", 40, 1);
        buf.extend_from_slice(&self.at.to_le_bytes()); // hl_dl_first
        buf.extend_from_slice(&0u16.to_le_bytes()); // hl_flags
        buf.push(u8::from(self.transposed)); // hl_zip_type
        buf.extend_from_slice(&[0u8; 5]);
        out.write_all(&buf)?;
        Ok(Some(hl))
    }
}
