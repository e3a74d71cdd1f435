//! The `.mrm` container: header, section table, checksums, and a bounded reader.

use super::MrmError;

/// The file's first eight bytes.
pub(crate) const MAGIC: [u8; 8] = *b"ASLODMRM";
/// Bytes before the section table: magic, version, section count.
const HEADER: usize = 16;
/// Bytes per section table entry: tag, CRC-32, offset, length.
const ENTRY: usize = 24;

/// CRC-32 (IEEE 802.3, the one zip and PNG use) of `bytes` (`crc32fast`: SIMD where the
/// CPU has it, so checking a file costs little beside reading it).
pub(crate) fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

/// Whether `bytes` have the checksum `crc`. Always under `cargo fuzz` (`cfg(fuzzing)`), so
/// the fuzzer reaches the checks behind the checksums, which it cannot forge.
fn checksum_ok(bytes: &[u8], crc: u32) -> bool {
    cfg!(fuzzing) || crc32(bytes) == crc
}

/// Sections to write: each tag with its bytes.
pub(crate) type Sections = Vec<([u8; 4], Vec<u8>)>;

/// Writes a file: the header, the table, its checksum, then each section's bytes.
pub(crate) fn write(version: u32, sections: &[([u8; 4], Vec<u8>)]) -> Vec<u8> {
    let table_end = HEADER + ENTRY * sections.len() + 4;
    let total = table_end + sections.iter().map(|(_, b)| b.len()).sum::<usize>();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(sections.len() as u32).to_le_bytes());
    let mut offset = table_end as u64;
    for (tag, bytes) in sections {
        out.extend_from_slice(tag);
        out.extend_from_slice(&crc32(bytes).to_le_bytes());
        out.extend_from_slice(&offset.to_le_bytes());
        out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        offset += bytes.len() as u64;
    }
    out.extend_from_slice(&crc32(&out).to_le_bytes());
    for (_, bytes) in sections {
        out.extend_from_slice(bytes);
    }
    out
}

/// One section of a file being read.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Section<'a> {
    pub(crate) tag: [u8; 4],
    /// Where its bytes start in the file.
    pub(crate) offset: u64,
    pub(crate) bytes: &'a [u8],
}

/// The sections of a file, checked: the magic, a version this reader knows, the table's
/// checksum, sections that lie one after the other to the end of the file, each with its
/// checksum, and tags in the order `expected` lists them (each at most once; those marked
/// required present). `base` is where `file` starts in the file on disk (a container nested
/// in another one's section), for the offsets in errors and sections.
pub(crate) fn read<'a>(
    file: &'a [u8],
    base: u64,
    supported: u32,
    expected: &[([u8; 4], bool)],
) -> Result<Vec<Section<'a>>, MrmError> {
    let mut sections = read_local(file, supported, expected).map_err(|e| e.shifted(base))?;
    for s in &mut sections {
        s.offset += base;
    }
    Ok(sections)
}

/// The version of a file that starts with the magic number, and the tag of its first
/// section (all zero when it has none); `None` for anything shorter.
pub(crate) fn peek(file: &[u8]) -> Option<(u32, [u8; 4])> {
    let version = u32::from_le_bytes(file.get(8..12)?.try_into().ok()?);
    let tag = file
        .get(16..20)
        .map_or([0; 4], |t| t.try_into().unwrap_or([0; 4]));
    Some((version, tag))
}

fn read_local<'a>(
    file: &'a [u8],
    supported: u32,
    expected: &[([u8; 4], bool)],
) -> Result<Vec<Section<'a>>, MrmError> {
    // A short file that does not even start like one is not an .mrm file.
    if !file.iter().zip(MAGIC).all(|(a, b)| *a == b) {
        return Err(MrmError::NotMrm);
    }
    let header = file.get(..HEADER).ok_or(MrmError::Truncated {
        section: "header".into(),
        offset: 0,
        needed: HEADER as u64,
    })?;
    let version = u32::from_le_bytes(header[8..12].try_into().unwrap_or_default());
    if version > supported {
        return Err(MrmError::NewerVersion {
            file: version,
            supported,
        });
    }
    if version == 0 {
        return Err(MrmError::Invalid {
            section: "header".into(),
            offset: 8,
            what: "format version 0",
        });
    }
    let count = u32::from_le_bytes(header[12..16].try_into().unwrap_or_default()) as usize;
    if count > expected.len() {
        return Err(MrmError::Invalid {
            section: "header".into(),
            offset: 12,
            what: "more sections than the format has",
        });
    }
    let table_end = HEADER + ENTRY * count + 4;
    let table = file.get(..table_end).ok_or(MrmError::Truncated {
        section: "section table".into(),
        offset: HEADER as u64,
        needed: table_end as u64,
    })?;
    let stored = u32::from_le_bytes(table[table_end - 4..].try_into().unwrap_or_default());
    if !checksum_ok(&table[..table_end - 4], stored) {
        return Err(MrmError::Checksum {
            section: "section table".into(),
            offset: HEADER as u64,
        });
    }
    let mut sections = Vec::with_capacity(count);
    let mut next = table_end as u64;
    let mut order = 0;
    for i in 0..count {
        let e = &table[HEADER + ENTRY * i..HEADER + ENTRY * (i + 1)];
        let tag: [u8; 4] = e[..4].try_into().unwrap_or_default();
        let crc = u32::from_le_bytes(e[4..8].try_into().unwrap_or_default());
        let offset = u64::from_le_bytes(e[8..16].try_into().unwrap_or_default());
        let length = u64::from_le_bytes(e[16..24].try_into().unwrap_or_default());
        let name = tag_name(tag);
        let entry_at = (HEADER + ENTRY * i) as u64;
        // In the format's order, each at most once.
        let Some(k) = expected[order..].iter().position(|(t, _)| *t == tag) else {
            let known = expected.iter().any(|(t, _)| *t == tag);
            return Err(MrmError::Invalid {
                section: name,
                offset: entry_at,
                what: if known {
                    "section out of order or repeated"
                } else {
                    "unknown section"
                },
            });
        };
        if let Some((missing, _)) = expected[order..order + k].iter().find(|(_, r)| *r) {
            return Err(MrmError::MissingSection(tag_name(*missing)));
        }
        order += k + 1;
        if offset != next {
            return Err(MrmError::Invalid {
                section: name,
                offset: entry_at + 8,
                what: "section does not start where the previous one ends",
            });
        }
        let end = offset
            .checked_add(length)
            .filter(|&e| e <= file.len() as u64);
        let Some(end) = end else {
            return Err(MrmError::Truncated {
                section: name,
                offset,
                needed: length,
            });
        };
        let bytes = &file[offset as usize..end as usize];
        if !checksum_ok(bytes, crc) {
            return Err(MrmError::Checksum {
                section: name,
                offset,
            });
        }
        sections.push(Section { tag, offset, bytes });
        next = end;
    }
    if let Some((missing, _)) = expected[order..].iter().find(|(_, r)| *r) {
        return Err(MrmError::MissingSection(tag_name(*missing)));
    }
    if next != file.len() as u64 {
        return Err(MrmError::Invalid {
            section: "file".into(),
            offset: next,
            what: "bytes after the last section",
        });
    }
    Ok(sections)
}

/// A tag as text (`?` for bytes that are not printable ASCII).
pub(crate) fn tag_name(tag: [u8; 4]) -> String {
    tag.iter()
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                b as char
            } else {
                '?'
            }
        })
        .collect::<String>()
        .trim_end()
        .to_owned()
}

/// `K` little-endian `f32`s from the start of `b`.
pub(crate) fn f32s<const K: usize>(b: &[u8]) -> [f32; K] {
    std::array::from_fn(|i| {
        f32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
    })
}

/// Reads little-endian values from one section, with errors that name it and the offset.
pub(crate) struct Reader<'a> {
    section: Section<'a>,
    at: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(section: Section<'a>) -> Self {
        Self { section, at: 0 }
    }

    /// The file offset of the section's first byte.
    pub(crate) fn start(&self) -> u64 {
        self.section.offset
    }

    /// The file offset of the next byte.
    pub(crate) fn offset(&self) -> u64 {
        self.section.offset + self.at as u64
    }

    /// An error about the value that starts at `at` (a position in the section).
    pub(crate) fn invalid(&self, at: usize, what: &'static str) -> MrmError {
        MrmError::Invalid {
            section: tag_name(self.section.tag),
            offset: self.section.offset + at as u64,
            what,
        }
    }

    /// The next `n` bytes.
    pub(crate) fn bytes(&mut self, n: usize) -> Result<&'a [u8], MrmError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.section.bytes.len());
        let Some(end) = end else {
            return Err(MrmError::Truncated {
                section: tag_name(self.section.tag),
                offset: self.offset(),
                needed: n as u64,
            });
        };
        let out = &self.section.bytes[self.at..end];
        self.at = end;
        Ok(out)
    }

    pub(crate) fn u8(&mut self) -> Result<u8, MrmError> {
        Ok(self.bytes(1)?[0])
    }

    pub(crate) fn u32(&mut self) -> Result<u32, MrmError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    pub(crate) fn f32(&mut self) -> Result<f32, MrmError> {
        Ok(f32::from_le_bytes(self.array()?))
    }

    pub(crate) fn u64(&mut self) -> Result<u64, MrmError> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    pub(crate) fn f64(&mut self) -> Result<f64, MrmError> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    /// A string: its length in bytes (`u32`), then UTF-8.
    pub(crate) fn string(&mut self) -> Result<String, MrmError> {
        let at = self.at;
        let n = self.u32()? as usize;
        let bytes = self.bytes(n)?;
        String::from_utf8(bytes.to_vec()).map_err(|_| self.invalid(at, "a string is not UTF-8"))
    }

    pub(crate) fn array<const N: usize>(&mut self) -> Result<[u8; N], MrmError> {
        let b = self.bytes(N)?;
        Ok(b.try_into().unwrap_or([0; N]))
    }

    /// `count` items of `N` bytes each, decoded by `f`. The count is checked against the
    /// bytes left before anything is allocated.
    pub(crate) fn items<const N: usize, T>(
        &mut self,
        count: usize,
        f: impl Fn([u8; N]) -> T,
    ) -> Result<Vec<T>, MrmError> {
        let bytes = self.bytes(count.saturating_mul(N))?;
        Ok(bytes
            .chunks_exact(N)
            .map(|c| f(c.try_into().unwrap_or([0; N])))
            .collect())
    }

    /// A whole section of `count` items of `N` bytes ([`items`](Self::items), then
    /// [`finish`](Self::finish)): the items, and the reader for errors about them.
    pub(crate) fn whole<const N: usize, T>(
        section: Section<'a>,
        count: usize,
        f: impl Fn([u8; N]) -> T,
    ) -> Result<(Vec<T>, Self), MrmError> {
        let mut r = Self::new(section);
        let items = r.items(count, f)?;
        r.finish()?;
        Ok((items, r))
    }

    /// Fails unless every byte was read.
    pub(crate) fn finish(&self) -> Result<(), MrmError> {
        if self.at == self.section.bytes.len() {
            Ok(())
        } else {
            Err(self.invalid(self.at, "bytes left over at the end of the section"))
        }
    }
}
