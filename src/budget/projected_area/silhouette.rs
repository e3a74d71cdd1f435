//! The silhouette table: the corners that outline a box, for each of the 64 face codes.

/// The face planes, one bit each, in the order of the [`silhouette`] code: bit `2k` is set
/// when the eye is below the box on axis `k` (it sees the `−k` face), bit `2k + 1` when it is
/// above (it sees the `+k` face).
pub(super) const fn face_loop(axis: usize, positive: bool) -> [u8; 4] {
    // With u = k+1, v = k+2 (cyclic), e_u × e_v = e_k, so (u, v) = (0,0) (1,0) (1,1) (0,1) runs
    // counter-clockwise seen from +k, and the reverse from −k.
    let u = (axis + 1) % 3;
    let v = (axis + 2) % 3;
    let base = if positive { 1u8 << axis } else { 0 };
    let uv: [(u8, u8); 4] = if positive {
        [(0, 0), (1, 0), (1, 1), (0, 1)]
    } else {
        [(0, 0), (0, 1), (1, 1), (1, 0)]
    };
    let mut out = [0u8; 4];
    let mut i = 0;
    while i < 4 {
        out[i] = base | (uv[i].0 << u) | (uv[i].1 << v);
        i += 1;
    }
    out
}

/// The outline for one code: `[len, c0, c1, …]`, `len` 0 for the 38 codes that cannot occur
/// with the eye outside the box.
const fn silhouette_row(code: usize) -> [u8; 7] {
    let mut row = [0u8; 7];
    if code == 0 {
        return row; // the eye is inside the box
    }
    let mut axis = 0;
    while axis < 3 {
        if (code >> (2 * axis)) & 3 == 3 {
            return row; // below and above the same axis at once
        }
        axis += 1;
    }
    // The directed boundary edges of every visible face, each face counter-clockwise from
    // outside. An edge shared by two visible faces appears once in each direction.
    let mut from = [0u8; 12];
    let mut to = [0u8; 12];
    let mut n = 0;
    axis = 0;
    while axis < 3 {
        let mut side = 0;
        while side < 2 {
            if (code >> (2 * axis + side)) & 1 == 1 {
                let face = face_loop(axis, side == 1);
                let mut e = 0;
                while e < 4 {
                    from[n] = face[e];
                    to[n] = face[(e + 1) % 4];
                    n += 1;
                    e += 1;
                }
            }
            side += 1;
        }
        axis += 1;
    }
    // The outline is what is left after the shared edges cancel.
    let mut keep = [false; 12];
    let mut start = u8::MAX;
    let mut i = 0;
    while i < n {
        keep[i] = true;
        let mut j = 0;
        while j < n {
            if from[j] == to[i] && to[j] == from[i] {
                keep[i] = false;
            }
            j += 1;
        }
        if keep[i] && from[i] < start {
            start = from[i];
        }
        i += 1;
    }
    // Chain the kept edges into a loop, starting from the lowest corner.
    let mut len = 0;
    let mut current = start;
    loop {
        row[1 + len] = current;
        len += 1;
        let mut next = u8::MAX;
        let mut k = 0;
        while k < n {
            if keep[k] && from[k] == current {
                next = to[k];
            }
            k += 1;
        }
        current = next;
        if current == start || len == 6 {
            break;
        }
    }
    row[0] = len as u8;
    row
}

const fn build_silhouette_table() -> [[u8; 7]; 64] {
    let mut table = [[0u8; 7]; 64];
    let mut code = 0;
    while code < 64 {
        table[code] = silhouette_row(code);
        code += 1;
    }
    table
}

/// Generated at compile time from the face geometry above; checked against projected corner
/// hulls in the tests.
static SILHOUETTE: [[u8; 7]; 64] = build_silhouette_table();

/// The box corners on the outline seen from an eye with face code `code` (only the low six bits
/// count), in counter-clockwise order as seen from the eye, starting at the lowest corner.
/// Corners are numbered as in [`Obb::corner`](crate::bounds::Obb::corner).
///
/// Bit `2k` of the code is set when the eye is below the box on axis `k` (`x < min`), bit
/// `2k + 1` when it is above (`x > max`). Of the 64 codes, 26 can occur with the eye outside
/// the box: 6 see one face and give 4 corners, 12 see two faces and 8 see three, which give 6.
/// The others (the eye inside, or on both sides of an axis) give an empty slice.
///
/// ```
/// use bevy_aslod::budget::silhouette;
///
/// // Eye above the box on z only: the outline is the +z face.
/// assert_eq!(silhouette(0b10_0000), &[4, 5, 7, 6]);
/// assert_eq!((0..64).filter(|&c| !silhouette(c).is_empty()).count(), 26);
/// ```
#[inline]
#[must_use]
pub fn silhouette(code: u8) -> &'static [u8] {
    let row = &SILHOUETTE[usize::from(code & 63)];
    &row[1..1 + usize::from(row[0])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_has_26_valid_codes() {
        let lens: Vec<usize> = (0..64u8).map(|c| silhouette(c).len()).collect();
        assert_eq!(lens.iter().filter(|&&l| l == 4).count(), 6);
        assert_eq!(lens.iter().filter(|&&l| l == 6).count(), 20);
        assert_eq!(lens.iter().filter(|&&l| l == 0).count(), 38);
        for code in 0..64u8 {
            let s = silhouette(code);
            let mut sorted = s.to_vec();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), s.len(), "code {code:06b} repeats a corner");
        }
    }
}
