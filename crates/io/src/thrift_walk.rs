//! A bounded walk over Thrift compact-protocol bytes, run on a Parquet file's footer and on
//! every page header of the columns read before the `parquet` crate decodes them.
//!
//! Why: the crate skips the elements of an unknown field's `list<bool>` (or a `map` of
//! booleans) as taking no bytes, where the compact protocol gives each one byte. A corrupt
//! page header whose list claims 2³¹ − 1 booleans then costs ≈ 8 s of decoding from 9 bytes,
//! and a few of them in one header run past a minute (issue 41, item 1: a fuzzed file that
//! made `physid inspect` hang at 10 MB of memory). This walk reads every field, element and
//! entry as the protocol lays it out, so each takes at least one byte, and refuses a count
//! larger than the bytes left. A header that passes holds no claim the bytes do not bear, so
//! the crate's own decoding of it, loops included, is bounded by its length: the readers make
//! progress per byte read.
//!
//! The compact protocol: <https://github.com/apache/thrift/blob/master/doc/specs/thrift-compact-protocol.md>.

/// Nesting depth allowed (the crate's own skip depth).
const MAX_DEPTH: usize = 64;

/// A cursor over Thrift compact-protocol bytes.
pub(crate) struct Walk<'a> {
    buf: &'a [u8],
    pos: usize,
}

/// Why the bytes are not a Thrift struct; `Short` when they end inside one or cannot hold
/// what it claims (more bytes may complete it).
#[derive(Debug, PartialEq)]
pub(crate) enum WalkError {
    /// The bytes end inside the struct, or a count claims more than they hold: why.
    Short(String),
    /// The bytes can never be a struct: the reason, at its byte.
    Bad(usize, String),
}

impl std::fmt::Display for WalkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Short(why) => write!(f, "{why}"),
            Self::Bad(at, why) => write!(f, "{why} at its byte {at}"),
        }
    }
}

impl<'a> Walk<'a> {
    pub(crate) fn new(buf: &'a [u8]) -> Self {
        Self { buf, pos: 0 }
    }

    fn left(&self) -> usize {
        self.buf.len() - self.pos
    }

    fn bad(&self, why: impl Into<String>) -> WalkError {
        WalkError::Bad(self.pos, why.into())
    }

    fn eof() -> WalkError {
        WalkError::Short("the bytes end inside it".into())
    }

    fn byte(&mut self) -> Result<u8, WalkError> {
        let b = *self.buf.get(self.pos).ok_or_else(Self::eof)?;
        self.pos += 1;
        Ok(b)
    }

    fn skip(&mut self, n: u64) -> Result<(), WalkError> {
        if n > self.left() as u64 {
            return Err(Self::eof());
        }
        self.pos += n as usize;
        Ok(())
    }

    /// An unsigned LEB128 varint (at most 10 bytes).
    fn varint(&mut self) -> Result<u64, WalkError> {
        let mut v = 0u64;
        for shift in (0..70).step_by(7) {
            let b = self.byte()?;
            v |= u64::from(b & 0x7F).checked_shl(shift).unwrap_or(0);
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(self.bad("a varint longer than 10 bytes"))
    }

    /// A zigzag varint.
    fn zigzag(&mut self) -> Result<i64, WalkError> {
        let v = self.varint()?;
        Ok((v >> 1) as i64 ^ -((v & 1) as i64))
    }

    /// A count of elements each taking at least `min_bytes`: refused when the bytes left
    /// cannot hold them.
    fn count(&mut self, n: u64, min_bytes: u64) -> Result<u64, WalkError> {
        if n.saturating_mul(min_bytes) > self.left() as u64 {
            return Err(WalkError::Short(format!(
                "a list or map at byte {} claims {n} elements with {} bytes left",
                self.pos,
                self.left()
            )));
        }
        Ok(n)
    }

    /// One value of compact type `ty` (a list or map element: booleans take one byte).
    fn value(&mut self, ty: u8, depth: usize) -> Result<(), WalkError> {
        if depth > MAX_DEPTH {
            return Err(self.bad(format!("nesting deeper than {MAX_DEPTH}")));
        }
        match ty {
            1..=3 => self.skip(1),
            4..=6 => self.varint().map(drop),
            7 => self.skip(8),
            8 => {
                let n = self.varint()?;
                self.skip(n)
            }
            9 | 10 => {
                let h = self.byte()?;
                let (size, elem) = (h >> 4, h & 0x0F);
                let n = if size == 15 {
                    self.varint()?
                } else {
                    u64::from(size)
                };
                // An empty list may be written as a single 0 byte, whatever its type.
                if n == 0 {
                    return Ok(());
                }
                for _ in 0..self.count(n, 1)? {
                    self.value(elem, depth + 1)?;
                }
                Ok(())
            }
            11 => {
                let n = self.varint()?;
                if n == 0 {
                    return Ok(());
                }
                let kv = self.byte()?;
                for _ in 0..self.count(n, 2)? {
                    self.value(kv >> 4, depth + 1)?;
                    self.value(kv & 0x0F, depth + 1)?;
                }
                Ok(())
            }
            12 => self.fields(depth + 1, |_, _, _| Ok(())),
            13 => self.skip(16),
            _ => Err(self.bad(format!("unknown Thrift type {ty}"))),
        }
    }

    /// The fields of one struct, up to and including its stop byte; `top` is told each
    /// integer field's id and value at this level (the rest are walked over).
    fn fields(
        &mut self,
        depth: usize,
        mut top: impl FnMut(&Self, i16, i64) -> Result<(), WalkError>,
    ) -> Result<(), WalkError> {
        if depth > MAX_DEPTH {
            return Err(self.bad(format!("nesting deeper than {MAX_DEPTH}")));
        }
        let mut last = 0i16;
        loop {
            let h = self.byte()?;
            if h == 0 {
                return Ok(());
            }
            let (delta, ty) = (h >> 4, h & 0x0F);
            let id = if delta == 0 {
                self.zigzag()? as i16
            } else {
                last.wrapping_add(i16::from(delta))
            };
            last = id;
            match ty {
                // A boolean field's value is its type.
                1 | 2 => {}
                4..=6 => {
                    let v = self.zigzag()?;
                    top(self, id, v)?;
                }
                _ => self.value(ty, depth)?,
            }
        }
    }

    /// One struct from the start: the bytes it takes; `top` sees its integer fields.
    pub(crate) fn structure(
        &mut self,
        top: impl FnMut(&Self, i16, i64) -> Result<(), WalkError>,
    ) -> Result<usize, WalkError> {
        let start = self.pos;
        self.fields(0, top)?;
        Ok(self.pos - start)
    }
}

/// A Parquet page header: its length in bytes and the compressed size of the page that
/// follows it (`PageHeader.compressed_page_size`, field 3).
pub(crate) fn page_header(buf: &[u8]) -> Result<(usize, i64), WalkError> {
    let mut size = None;
    let len = Walk::new(buf).structure(|w, id, v| {
        if id == 3 {
            if !(0..=i64::from(i32::MAX)).contains(&v) {
                return Err(w.bad(format!("a page size of {v} bytes")));
            }
            size = Some(v);
        }
        Ok(())
    })?;
    let size = size.ok_or_else(|| WalkError::Bad(len, "no page size".into()))?;
    Ok((len, size))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An unknown field (id 100) holding a list of 2³¹ − 1 booleans, in 9 bytes.
    const BOOLS: [u8; 9] = [0x09, 0xC8, 0x01, 0xF1, 0xFF, 0xFF, 0xFF, 0xFF, 0x07];

    #[test]
    fn a_list_claiming_more_elements_than_bytes_is_refused_at_once() {
        let mut b = BOOLS.to_vec();
        b.push(0);
        let e = Walk::new(&b).structure(|_, _, _| Ok(())).unwrap_err();
        assert!(
            matches!(&e, WalkError::Short(why) if why.contains("claims 2147483647 elements")),
            "{e:?}"
        );
    }

    #[test]
    fn booleans_in_a_list_take_a_byte_each() {
        // A list of 3 booleans (size 3, type 1), then the stop byte.
        let b = [0x09, 0xC8, 0x01, 0x31, 1, 2, 1, 0];
        assert_eq!(Walk::new(&b).structure(|_, _, _| Ok(())), Ok(8));
        // The same, one element short: the struct is not complete.
        assert!(matches!(
            Walk::new(&b[..5]).structure(|_, _, _| Ok(())),
            Err(WalkError::Short(_))
        ));
        assert!(matches!(
            Walk::new(&b[..7]).structure(|_, _, _| Ok(())),
            Err(WalkError::Short(_))
        ));
    }

    #[test]
    fn a_page_header_gives_its_length_and_page_size() {
        // type = 0 (i32 field 1), uncompressed 100 (field 2), compressed 60 (field 3),
        // then a struct field 5 { i32 field 1 = 7 } and the stop.
        let b = [
            0x15, 0x00, 0x15, 0xC8, 0x01, 0x15, 0x78, 0x2C, 0x15, 0x0E, 0x00, 0x00,
        ];
        assert_eq!(page_header(&b), Ok((12, 60)));
        let mut neg = b;
        neg[6] = 0x77; // zigzag −60
        assert!(matches!(page_header(&neg), Err(WalkError::Bad(..))));
    }

    #[test]
    fn nesting_is_bounded() {
        // 100 nested lists of lists, each of one element.
        let mut b = vec![0x09, 0xC8, 0x01];
        b.extend(std::iter::repeat_n(0x19, 100));
        b.push(0);
        let e = Walk::new(&b).structure(|_, _, _| Ok(())).unwrap_err();
        assert!(
            matches!(&e, WalkError::Bad(_, why) if why.contains("nesting")),
            "{e:?}"
        );
    }
}
