//! Writing an MDF4 file: whole through `falcon_mdf` ([`write_mdf`]) or as the samples come
//! ([`MdfWriter`]): the streaming writer starts from `falcon_mdf`'s header and writes its own
//! data, list and compressed blocks after it, patching the header's links at their byte
//! offsets — all of that byte-level work is in this file, behind [`MdfWriter`].

use super::*;

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
pub(super) struct Zip {
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

/// Where the streaming writer patches its header: found from HD (at 64) → its first DG → the
/// DG's first CG and its data block.
struct Layout {
    /// The data block (a `##DT`, the file's last block, while uncompressed).
    dt_off: u64,
    /// The DG's link to its data.
    dg_data_link_off: u64,
    /// The CG's record count.
    cycle_count_off: u64,
    /// Bytes a record.
    record_len: usize,
}

impl Layout {
    /// From `at(offset, len)`, the file's bytes there (`None` past its end); the error says
    /// which block is not where it should be.
    fn find(at: impl Fn(u64, usize) -> Option<Vec<u8>>) -> Result<Self, &'static str> {
        let u64_at = |o: u64| at(o, 8).map(|b| u64::from_le_bytes(b.try_into().unwrap_or([0; 8])));
        // Saturating: a link read from a damaged file points past its end, not into a panic.
        let dg = u64_at(64 + 24).ok_or("no HD")?;
        let cg = u64_at(dg.saturating_add(32)).ok_or("no DG")?;
        let dt_off = u64_at(dg.saturating_add(40)).ok_or("no DG data link")?;
        let links = u64_at(cg.saturating_add(16)).ok_or("no CG")?;
        let cycle_count_off = cg
            .saturating_add(links.saturating_mul(8))
            .saturating_add(32);
        let record_len = at(cycle_count_off.saturating_add(16), 4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap_or([0; 4])) as usize)
            .ok_or("CG record size")?;
        if at(dg, 4).as_deref() != Some(b"##DG") || at(cg, 4).as_deref() != Some(b"##CG") {
            return Err("no DG and CG where the header links them");
        }
        Ok(Self {
            dt_off,
            dg_data_link_off: dg.saturating_add(40),
            cycle_count_off,
            record_len,
        })
    }
}

/// An uncompressed MDF4 file whose [`MdfWriter`] failed (a full disk, an I/O error) and was
/// dropped: its data block's length and record count set, in place (not a byte added), to the
/// records wholly on the disk — each sample that reached the disk readable, those after its
/// last commit too. The records are synced before the count that claims them. The records kept;
/// `None` for a compressed file (its blocks are listed only when it is closed).
pub fn settle_mdf(path: impl AsRef<Path>) -> Result<Option<u64>, IoError> {
    use std::io::{Read, Seek, SeekFrom, Write};
    let p = path.as_ref().display().to_string();
    let os = |source| IoError::Os {
        path: p.clone(),
        source,
    };
    let file = crate::lock::open_to_mend(path.as_ref())?;
    let read_at = |at: u64, n: usize| {
        let mut f = &file;
        f.seek(SeekFrom::Start(at)).ok()?;
        let mut b = vec![0; n];
        f.read_exact(&mut b).ok()?;
        Some(b)
    };
    let layout = Layout::find(read_at)
        .map_err(|what| mdf_err(&p, format!("not a file physid's MDF4 writer left: {what}")))?;
    if read_at(layout.dt_off, 4).as_deref() != Some(b"##DT") || layout.record_len == 0 {
        return Ok(None);
    }
    let len = file.metadata().map_err(os)?.len();
    let records = len.saturating_sub(layout.dt_off.saturating_add(24)) / layout.record_len as u64;
    file.sync_data().map_err(os)?;
    let mut f = &file;
    let dt_len = 24 + records * layout.record_len as u64;
    f.seek(SeekFrom::Start(layout.dt_off.saturating_add(8)))
        .map_err(os)?;
    f.write_all(&dt_len.to_le_bytes()).map_err(os)?;
    f.seek(SeekFrom::Start(layout.cycle_count_off))
        .map_err(os)?;
    f.write_all(&records.to_le_bytes()).map_err(os)?;
    file.sync_data().map_err(os)?;
    Ok(Some(records))
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
        let Layout {
            dt_off,
            dg_data_link_off,
            cycle_count_off,
            record_len,
        } = Layout::find(|at, n| {
            let at = usize::try_from(at).ok()?;
            header.get(at..at.checked_add(n)?).map(<[u8]>::to_vec)
        })
        .map_err(|what| {
            mdf_err(
                &p,
                format!("unexpected block layout from falcon_mdf: {what}"),
            )
        })?;
        let dt = usize::try_from(dt_off)
            .ok()
            .and_then(|d| header.get(d..d + 4));
        if dt != Some(b"##DT")
            || dt_off + 24 != header.len() as u64
            || record_len != 8 * (names.len() + 1)
        {
            return Err(mdf_err(
                &p,
                "unexpected block layout from falcon_mdf: not one empty DT block of float64 records at the end",
            ));
        }
        let file = crate::lock::create(path.as_ref())?;
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
            dg_data_link_off,
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
pub(super) fn block_header(buf: &mut Vec<u8>, id: &[u8; 4], length: u64, links: u64) {
    buf.extend_from_slice(id);
    buf.extend_from_slice(&[0u8; 4]);
    buf.extend_from_slice(&length.to_le_bytes());
    buf.extend_from_slice(&links.to_le_bytes());
}

impl Zip {
    /// Deflate the records gathered (if any) into a `##DZ` at the end of the file.
    pub(super) fn flush(
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
    pub(super) fn list(
        &self,
        out: &mut impl std::io::Write,
    ) -> Result<Option<u64>, std::io::Error> {
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
