//! Byte surgery on `.mrm` files: their containers, and resealing their checksums after a
//! change made on purpose.

/// CRC-32 (IEEE), as the format uses.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// The section table of the well-formed container at `start`: (entry offset, data offset,
/// length), absolute.
pub fn table(bytes: &[u8], start: usize) -> Vec<(usize, usize, usize)> {
    let n = u32::from_le_bytes(bytes[start + 12..start + 16].try_into().unwrap()) as usize;
    (0..n)
        .map(|i| {
            let e = start + 16 + 24 * i;
            let off = u64::from_le_bytes(bytes[e + 8..e + 16].try_into().unwrap()) as usize;
            let len = u64::from_le_bytes(bytes[e + 16..e + 24].try_into().unwrap()) as usize;
            (e, start + off, len)
        })
        .collect()
}

/// Where the containers of a well-formed file start: the file itself and every container
/// nested in a section (each starts with the magic number), innermost last.
pub fn containers(bytes: &[u8]) -> Vec<usize> {
    (0..bytes.len().saturating_sub(7))
        .filter(|&i| &bytes[i..i + 8] == b"ASLODMRM")
        .collect()
}

/// Makes every checksum of the container at `start` match again (as a file changed on
/// purpose would), where its table still describes sections inside the file.
pub fn reseal_at(bytes: &mut [u8], start: usize) {
    let Some(n) = bytes
        .get(start + 12..start + 16)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()) as usize)
    else {
        return;
    };
    let end = start + 16 + 24 * n;
    if n > 64 || bytes.len() < end + 4 {
        return;
    }
    for i in 0..n {
        let e = start + 16 + 24 * i;
        let off = u64::from_le_bytes(bytes[e + 8..e + 16].try_into().unwrap());
        let len = u64::from_le_bytes(bytes[e + 16..e + 24].try_into().unwrap());
        if let Some(data) = off
            .checked_add(start as u64)
            .and_then(|o| Some((o, o.checked_add(len)?)))
            .filter(|&(_, x)| x <= bytes.len() as u64)
            .map(|(o, x)| &bytes[o as usize..x as usize])
        {
            let crc = crc32(data);
            bytes[e + 4..e + 8].copy_from_slice(&crc.to_le_bytes());
        }
    }
    let crc = crc32(&bytes[start..end]);
    bytes[end..end + 4].copy_from_slice(&crc.to_le_bytes());
}

/// Reseals every container, the innermost first (a nested container's checksums are part
/// of its parent's section).
pub fn reseal(bytes: &mut [u8], starts: &[usize]) {
    for &start in starts.iter().rev() {
        reseal_at(bytes, start);
    }
}
