//! Reading an MDF4 file: whole ([`read_mdf`]) or a chunk at a time ([`MdfChunks`]), the
//! groups' masters, record counts and time bases checked.

use super::*;

/// Read an MDF4 file (module docs); `channels` selects channels by name (the master comes
/// with them).
pub fn read_mdf(path: impl AsRef<Path>, channels: Option<&[String]>) -> Result<Recording, IoError> {
    let p = path.as_ref().display().to_string();
    crate::contained(&p, "MDF4", || read_mdf_inner(path.as_ref(), &p, channels))
}

/// What a read takes from an MDF4 file: the channels chosen, their group and its master, and
/// the recording's basis and metadata (no channels yet).
pub(super) struct Plan<'f> {
    chosen: Vec<&'f falcon_mdf::model::Channel>,
    group: (usize, usize),
    master: Option<&'f falcon_mdf::model::Channel>,
    /// The master's name and unit in the recording (`t` [s] or `theta` [rad]).
    axis: (&'static str, &'static str),
    rec: Recording,
}

impl<'f> Plan<'f> {
    pub(super) fn of(
        file: &'f Mf4File,
        p: &str,
        channels: Option<&[String]>,
    ) -> Result<Self, IoError> {
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

pub(super) fn read_mdf_inner(
    path: &Path,
    p: &str,
    channels: Option<&[String]>,
) -> Result<Recording, IoError> {
    let file = Mf4File::open_buffered(path).map_err(|e| mdf_err(p, e))?;
    let plan = Plan::of(&file, p, channels)?;
    read_planned(&file, p, plan, channels.is_some())
}

/// The whole of a plan's channels; a channel of another group is taken when its time base is
/// the master's (else refused when asked for by name, skipped and named in `meta["skipped"]`
/// when reading everything).
pub(super) fn read_planned(
    file: &Mf4File,
    p: &str,
    plan: Plan,
    asked: bool,
) -> Result<Recording, IoError> {
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
pub(super) enum MdfMsg {
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
pub(super) fn declared_cycles(path: &Path, dg: usize, cg: usize) -> Option<u64> {
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
pub(super) fn produce(
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
pub(super) struct Layout {
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
    pub(super) fn of(
        file: &Mf4File,
        p: &str,
        plan: &Plan,
        asked: bool,
    ) -> Result<Option<Self>, IoError> {
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
pub(super) fn different_bases(a: &str, b: &str, na: usize, nb: usize) -> String {
    let how = if na == nb {
        format!("{na} samples each, at different times")
    } else {
        format!("{na} and {nb} samples")
    };
    format!("channels '{a}' and '{b}' are on different time bases ({how}): read them separately")
}

/// Whether two masters hold the same times, compared a window at a time (the other validated
/// as [`Mf4File::channel_timestamps`] validates it).
pub(super) fn same_times(
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
pub(super) fn check_record_count(
    file: &Mf4File,
    (dg, cg): (usize, usize),
    p: &str,
) -> Result<(), IoError> {
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
