//! Vertex attributes beyond the ones every path reads by name: a second UV set, vertex
//! colours, and any custom attribute, in any of Bevy's vertex formats.
//!
//! A [`VertexAttribute`] is raw little-endian bytes, one record of [`AttributeFormat::size`]
//! bytes per vertex, under the name and id Bevy knows it by. Levels of detail are subsets of
//! the source vertices, so every path carries these records unchanged: picked, scattered or
//! appended with the positions, never recomputed.

/// The scalar type of an attribute's components, and how a shader reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scalar {
    /// `f32`.
    F32,
    /// IEEE half-precision float (`f16`), read as `f32`.
    F16,
    /// `u32`.
    U32,
    /// `i32`.
    I32,
    /// `u16`, read as an integer.
    U16,
    /// `i16`, read as an integer.
    I16,
    /// `u16`, read as a float in `[0, 1]`.
    Unorm16,
    /// `i16`, read as a float in `[-1, 1]`.
    Snorm16,
    /// `u8`, read as an integer.
    U8,
    /// `i8`, read as an integer.
    I8,
    /// `u8`, read as a float in `[0, 1]`.
    Unorm8,
    /// `i8`, read as a float in `[-1, 1]`.
    Snorm8,
    /// `f64`.
    F64,
    /// `u8`, read as a float in `[0, 1]`, four of them stored blue, green, red, alpha (Bevy's
    /// `Unorm8x4Bgra`).
    Bgra8,
}

impl Scalar {
    /// Bytes of one component.
    #[must_use]
    pub const fn size(self) -> usize {
        match self {
            Self::F64 => 8,
            Self::F32 | Self::U32 | Self::I32 => 4,
            Self::F16 | Self::U16 | Self::I16 | Self::Unorm16 | Self::Snorm16 => 2,
            Self::U8 | Self::I8 | Self::Unorm8 | Self::Snorm8 | Self::Bgra8 => 1,
        }
    }

    /// The code of this scalar type in `.mrm` files.
    pub(crate) const fn code(self) -> u8 {
        self as u8
    }

    /// The scalar type of a `.mrm` code.
    pub(crate) fn from_code(code: u8) -> Option<Self> {
        const ALL: [Scalar; 14] = [
            Scalar::F32,
            Scalar::F16,
            Scalar::U32,
            Scalar::I32,
            Scalar::U16,
            Scalar::I16,
            Scalar::Unorm16,
            Scalar::Snorm16,
            Scalar::U8,
            Scalar::I8,
            Scalar::Unorm8,
            Scalar::Snorm8,
            Scalar::F64,
            Scalar::Bgra8,
        ];
        ALL.get(usize::from(code)).copied()
    }
}

/// The format of one attribute record: 1 to 4 components of one [`Scalar`] type (every
/// format a Bevy mesh attribute can hold: 3 components only for 32- and 64-bit scalars,
/// [`Scalar::Bgra8`] only with 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AttributeFormat {
    /// The components' type.
    pub scalar: Scalar,
    /// How many components each vertex has: 1 to 4.
    pub components: u8,
}

impl AttributeFormat {
    /// Bytes of one vertex's record.
    #[must_use]
    pub const fn size(self) -> usize {
        self.scalar.size() * self.components as usize
    }

    /// Whether Bevy has a vertex format for it: 1, 2 or 4 components, 3 as well for 32- and
    /// 64-bit scalars, and exactly 4 for [`Scalar::Bgra8`].
    #[must_use]
    pub const fn is_valid(self) -> bool {
        match (self.scalar, self.components) {
            (Scalar::Bgra8, c) => c == 4,
            (Scalar::F32 | Scalar::U32 | Scalar::I32 | Scalar::F64, 1..=4) | (_, 1 | 2 | 4) => true,
            _ => false,
        }
    }
}

/// Bevy's id of `Mesh::ATTRIBUTE_UV_1` (glTF `TEXCOORD_1`).
pub const UV_1_ID: u64 = 3;
/// Bevy's id of `Mesh::ATTRIBUTE_TANGENT` (glTF `TANGENT`), kept in
/// [`IndexedMesh::tangents`](super::IndexedMesh::tangents), never as a [`VertexAttribute`].
pub const TANGENT_ID: u64 = 4;
/// Bevy's id of `Mesh::ATTRIBUTE_COLOR` (glTF `COLOR_0`).
pub const COLOR_ID: u64 = 5;
/// The ids Bevy gives its standard attributes (positions, normals, UV 0 and 1, tangents,
/// colours, joint weights and indices): the ones [`IndexedMesh`](super::IndexedMesh) keeps by
/// name or knows how to read.
pub const STANDARD_IDS: std::ops::Range<u64> = 0..8;

/// One vertex attribute carried as bytes: a second UV set, vertex colours, or a custom
/// attribute.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexAttribute {
    /// The name shaders and Bevy know it by (`Vertex_Uv_1`, `Vertex_Color`, or the custom
    /// attribute's own).
    pub name: String,
    /// Bevy's `MeshVertexAttributeId`: its place in the interleaved vertex buffer and its
    /// identity. [`UV_1_ID`] and [`COLOR_ID`] for the standard ones.
    pub id: u64,
    /// The format of each vertex's record.
    pub format: AttributeFormat,
    /// `vertex_count × format.size()` little-endian bytes.
    pub data: Vec<u8>,
}

impl VertexAttribute {
    /// The attribute from one `f32` record of `N` components per vertex.
    #[must_use]
    pub fn from_f32<const N: usize>(name: &str, id: u64, values: &[[f32; N]]) -> Self {
        Self {
            name: name.to_string(),
            id,
            format: AttributeFormat {
                scalar: Scalar::F32,
                components: N as u8,
            },
            data: values
                .iter()
                .flatten()
                .flat_map(|x| x.to_le_bytes())
                .collect(),
        }
    }

    /// The records as `f32` arrays of `N` components, when the format is `N` × [`Scalar::F32`].
    #[must_use]
    pub fn to_f32<const N: usize>(&self) -> Option<Vec<[f32; N]>> {
        if self.format.scalar != Scalar::F32 || usize::from(self.format.components) != N {
            return None;
        }
        Some(
            self.data
                .chunks_exact(4 * N)
                .map(|record| {
                    std::array::from_fn(|k| {
                        f32::from_le_bytes([
                            record[4 * k],
                            record[4 * k + 1],
                            record[4 * k + 2],
                            record[4 * k + 3],
                        ])
                    })
                })
                .collect(),
        )
    }

    /// Number of whole records in [`data`](Self::data).
    #[must_use]
    pub fn len(&self) -> usize {
        self.data.len() / self.format.size().max(1)
    }

    /// Whether the attribute has no records.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The record of vertex `v`.
    ///
    /// # Panics
    /// Panics when `v` is out of range.
    #[must_use]
    pub fn record(&self, v: usize) -> &[u8] {
        let s = self.format.size();
        &self.data[v * s..(v + 1) * s]
    }

    /// The same attribute with the records of `vertices`, in that order.
    #[must_use]
    pub fn gather(&self, vertices: &[u32]) -> Self {
        let mut data = Vec::with_capacity(vertices.len() * self.format.size());
        for &v in vertices {
            data.extend_from_slice(self.record(v as usize));
        }
        Self {
            data,
            ..self.without_data()
        }
    }

    /// The same name, id and format with no records.
    #[must_use]
    pub fn without_data(&self) -> Self {
        Self {
            name: self.name.clone(),
            id: self.id,
            format: self.format,
            data: Vec::new(),
        }
    }

    /// The first vertex whose record holds a float component that is NaN or infinite.
    #[must_use]
    pub fn first_non_finite(&self) -> Option<usize> {
        let s = self.format.size();
        match self.format.scalar {
            Scalar::F32 => self
                .data
                .chunks_exact(4)
                .position(|x| !f32::from_le_bytes([x[0], x[1], x[2], x[3]]).is_finite())
                .map(|k| k * 4 / s),
            // An f16 whose exponent bits are all set is infinite or NaN.
            Scalar::F16 => self
                .data
                .chunks_exact(2)
                .position(|x| u16::from_le_bytes([x[0], x[1]]) & 0x7c00 == 0x7c00)
                .map(|k| k * 2 / s),
            Scalar::F64 => self
                .data
                .chunks_exact(8)
                .position(|x| {
                    !f64::from_le_bytes([x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7]])
                        .is_finite()
                })
                .map(|k| k * 8 / s),
            _ => None,
        }
    }
}

/// The attributes of a vertex table beyond the named ones, all with one record per vertex.
pub(crate) fn gather_all(attributes: &[VertexAttribute], vertices: &[u32]) -> Vec<VertexAttribute> {
    attributes.iter().map(|a| a.gather(vertices)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_and_gather() {
        let a = VertexAttribute::from_f32("Vertex_Uv_1", UV_1_ID, &[[0.0, 1.0], [2.0, 3.0]]);
        assert_eq!(a.len(), 2);
        assert_eq!(a.to_f32::<2>(), Some(vec![[0.0, 1.0], [2.0, 3.0]]));
        assert_eq!(a.to_f32::<3>(), None);
        let g = a.gather(&[1, 1, 0]);
        assert_eq!(
            g.to_f32::<2>(),
            Some(vec![[2.0, 3.0], [2.0, 3.0], [0.0, 1.0]])
        );
        assert_eq!(a.first_non_finite(), None);
        let nan = VertexAttribute::from_f32("c", 99, &[[0.0; 4], [1.0, f32::NAN, 0.0, 0.0]]);
        assert_eq!(nan.first_non_finite(), Some(1));
        for code in 0..14 {
            assert_eq!(Scalar::from_code(code).map(Scalar::code), Some(code));
        }
        assert_eq!(Scalar::from_code(14), None);
    }
}
