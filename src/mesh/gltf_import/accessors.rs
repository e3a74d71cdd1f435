//! Accessors: typed attribute data decoded from the buffers, every read bounds-checked.

use super::container::gltf_error;
use crate::mesh::{MeshError, MeshResult};
use gltf::Accessor;
use gltf::accessor::DataType;
use std::borrow::Cow;

/// Accessors without a buffer view are zeros of the declared count; a count above this
/// would only exhaust memory, so such files are rejected.
const MAX_ZERO_FILLED_ELEMENTS: usize = 1 << 24;

/// The contents of the document's buffers, by buffer index. What decoding them allocates
/// was checked against the limits before they were read ([`Plan`](super::plan::Plan)).
pub(super) struct Data<'a> {
    pub(super) buffers: Vec<Cow<'a, [u8]>>,
}

impl Data<'_> {
    /// Reads `N`-component float data: `f32`, or integers (normalized or not, as
    /// `KHR_mesh_quantization` allows).
    pub(super) fn read_floats<const N: usize>(
        &self,
        accessor: &Accessor<'_>,
        what: &str,
    ) -> MeshResult<Vec<[f32; N]>> {
        let ty = accessor.data_type();
        if accessor.dimensions().multiplicity() != N {
            return Err(type_error(accessor, what, &format!("{N} components")));
        }
        let normalized = accessor.normalized();
        let c = ty.size();
        self.read(accessor, [0.0; N], |b| {
            std::array::from_fn(|j| component_f32(&b[j * c..j * c + c], ty, normalized))
        })
    }

    /// Reads `N`-component unsigned integer data of the given component types.
    pub(super) fn read_uints<const N: usize>(
        &self,
        accessor: &Accessor<'_>,
        what: &str,
        allowed: &[DataType],
    ) -> MeshResult<Vec<[u32; N]>> {
        let ty = accessor.data_type();
        if accessor.dimensions().multiplicity() != N || !allowed.contains(&ty) {
            let types: Vec<String> = allowed.iter().map(|t| format!("{t:?}")).collect();
            let expected = format!("{N} components of type {}", types.join(" or "));
            return Err(type_error(accessor, what, &expected));
        }
        let c = ty.size();
        self.read(accessor, [0; N], |b| {
            std::array::from_fn(|j| match b[j * c..j * c + c] {
                [x] => u32::from(x),
                [x0, x1] => u32::from(u16::from_le_bytes([x0, x1])),
                [x0, x1, x2, x3] => u32::from_le_bytes([x0, x1, x2, x3]),
                _ => 0,
            })
        })
    }

    /// Decodes every element of an accessor, sparse substitution included, with `decode`
    /// getting exactly one element's bytes. Nothing is read that was not bounds-checked.
    fn read<T: Clone>(
        &self,
        accessor: &Accessor<'_>,
        zero: T,
        decode: impl Fn(&[u8]) -> T,
    ) -> MeshResult<Vec<T>> {
        let a = accessor.index();
        let count = accessor.count();
        let size = accessor.size();
        if count == 0 {
            return Err(gltf_error(format!(
                "accessors[{a}].count: must be at least 1"
            )));
        }
        let mut out = match accessor.view() {
            Some(view) => {
                let bytes = self.view_bytes(&view)?;
                let stride = stride_within(accessor, &view, bytes.len())?;
                let start = accessor.offset();
                (0..count)
                    .map(|i| decode(&bytes[start + i * stride..][..size]))
                    .collect()
            }
            None if count > MAX_ZERO_FILLED_ELEMENTS => {
                return Err(gltf_error(format!(
                    "accessors[{a}]: {count} zero-initialised elements is more than this \
                     importer accepts ({MAX_ZERO_FILLED_ELEMENTS})"
                )));
            }
            None => vec![zero; count],
        };

        if let Some(sparse) = accessor.sparse() {
            let n = sparse.count();
            if n > count {
                return Err(gltf_error(format!(
                    "accessors[{a}].sparse.count: {n} exceeds the accessor count {count}"
                )));
            }
            // `n` items of `size` bytes from `offset` into a view, or an error naming `what`.
            let items = |view: gltf::buffer::View<'_>, offset: usize, size: usize, what: &str| {
                let bytes = self.view_bytes(&view)?;
                n.checked_mul(size)
                    .and_then(|len| bytes.get(offset..)?.get(..len))
                    .ok_or_else(|| {
                        gltf_error(format!(
                            "accessors[{a}].sparse.{what}: {n} {what} do not fit in their buffer \
                             view"
                        ))
                    })
            };
            let indices = sparse.indices();
            let index_size = indices.index_type().size();
            let index_bytes = items(indices.view(), indices.offset(), index_size, "indices")?;
            let values = sparse.values();
            let value_bytes = items(values.view(), values.offset(), size, "values")?;
            for (k, raw) in index_bytes.chunks_exact(index_size).enumerate() {
                let target = match *raw {
                    [b] => usize::from(b),
                    [b0, b1] => usize::from(u16::from_le_bytes([b0, b1])),
                    [b0, b1, b2, b3] => u32::from_le_bytes([b0, b1, b2, b3]) as usize,
                    _ => unreachable!("sparse index sizes are 1, 2 or 4"),
                };
                let slot = out.get_mut(target).ok_or_else(|| {
                    gltf_error(format!(
                        "accessors[{a}].sparse.indices: index {target} is out of range \
                         ({count} elements)"
                    ))
                })?;
                *slot = decode(&value_bytes[k * size..][..size]);
            }
        }
        Ok(out)
    }

    /// The bytes of a buffer view, checked against its buffer.
    fn view_bytes(&self, view: &gltf::buffer::View<'_>) -> MeshResult<&[u8]> {
        let buffer = &self.buffers[view.buffer().index()];
        view_within(view, buffer.len()).map(|range| &buffer[range])
    }
}

/// The byte range of `view` in its buffer, checked against the buffer's `length`.
///
/// # Errors
/// A view that reaches past its buffer.
pub(super) fn view_within(
    view: &gltf::buffer::View<'_>,
    length: usize,
) -> MeshResult<std::ops::Range<usize>> {
    view.offset()
        .checked_add(view.length())
        .filter(|&end| end <= length)
        .map(|end| view.offset()..end)
        .ok_or_else(|| {
            gltf_error(format!(
                "bufferViews[{}]: bytes {}..{} lie outside buffers[{}] ({length} bytes)",
                view.index(),
                view.offset(),
                view.offset().saturating_add(view.length()),
                view.buffer().index(),
            ))
        })
}

/// The stride of `accessor`'s elements in `view`, once they are checked to fit in its
/// `length` bytes.
///
/// # Errors
/// A stride below the element size, or elements that reach past the view.
pub(super) fn stride_within(
    accessor: &Accessor<'_>,
    view: &gltf::buffer::View<'_>,
    length: usize,
) -> MeshResult<usize> {
    let (a, count, size) = (accessor.index(), accessor.count(), accessor.size());
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return Err(gltf_error(format!(
            "accessors[{a}]: bufferViews[{}].byteStride {stride} is smaller than the element \
             size {size}",
            view.index()
        )));
    }
    let start = accessor.offset();
    let needed = stride
        .checked_mul(count.saturating_sub(1))
        .and_then(|n| n.checked_add(start))
        .and_then(|n| n.checked_add(size));
    if needed.is_none_or(|n| n > length) {
        return Err(gltf_error(format!(
            "accessors[{a}]: {count} elements of {size} bytes (stride {stride}, offset \
             {start}) do not fit in bufferViews[{}] ({length} bytes)",
            view.index(),
        )));
    }
    Ok(stride)
}

pub(super) fn type_error(accessor: &Accessor<'_>, what: &str, expected: &str) -> MeshError {
    gltf_error(format!(
        "{what} (accessors[{}]): expected {expected}, found {:?} of {:?}",
        accessor.index(),
        accessor.dimensions(),
        accessor.data_type()
    ))
}

/// One component as a float, with the specification's normalization formulas.
fn component_f32(b: &[u8], ty: DataType, normalized: bool) -> f32 {
    match (ty, b) {
        (DataType::F32, &[b0, b1, b2, b3]) => f32::from_le_bytes([b0, b1, b2, b3]),
        (DataType::U32, &[b0, b1, b2, b3]) => u32::from_le_bytes([b0, b1, b2, b3]) as f32,
        (DataType::I8, &[x]) if normalized => (f32::from(x as i8) / 127.0).max(-1.0),
        (DataType::I8, &[x]) => f32::from(x as i8),
        (DataType::U8, &[x]) if normalized => f32::from(x) / 255.0,
        (DataType::U8, &[x]) => f32::from(x),
        (DataType::I16, &[x0, x1]) => {
            let v = f32::from(i16::from_le_bytes([x0, x1]));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        (DataType::U16, &[x0, x1]) => {
            let v = f32::from(u16::from_le_bytes([x0, x1]));
            if normalized { v / 65535.0 } else { v }
        }
        _ => 0.0,
    }
}
