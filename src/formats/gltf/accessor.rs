//! Reading accessors from validated bytes. Every index (accessor, buffer view, buffer) is looked up
//! with `get`, every type is checked against what the caller needs, and every byte range is
//! computed with checked arithmetic and compared with the data before an element is read or a
//! vector is sized. Elements are decoded in place: no allocation per element.

use std::borrow::Cow;

use gltf::json;

use super::container::Model;
use gltf::json::accessor::{ComponentType, GenericComponentType, Type};
use gltf::json::validation::Checked;

use super::super::{Limits, ReadError};

/// The loaded buffers of an asset, by index (`None`: not needed by any mesh, so never loaded).
pub struct Data<'a> {
    pub root: &'a Model,
    pub buffers: Vec<Option<Cow<'a, [u8]>>>,
    /// The bytes behind `buffers`, a file that several buffers share counted once.
    pub buffer_bytes: u64,
    pub limits: &'a Limits,
}

/// `count` elements of `size` bytes, `stride` bytes apart, inside `bytes` (checked on creation).
struct Strided<'a> {
    bytes: &'a [u8],
    stride: usize,
    size: usize,
    count: usize,
}

impl<'a> Strided<'a> {
    fn element(&self, i: usize) -> &'a [u8] {
        let at = i * self.stride;
        &self.bytes[at..at + self.size]
    }
}

fn err(msg: String) -> ReadError {
    ReadError::new(msg)
}

pub(crate) fn component_name(c: ComponentType) -> &'static str {
    match c {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

/// The name glTF's JSON gives an accessor type (`VEC3`, ...).
pub(crate) fn type_name(t: Type) -> &'static str {
    match t {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

/// The accessor at `index`, or an error naming who referred to it.
pub fn get<'r>(root: &'r Model, index: usize, what: &str) -> Result<&'r json::Accessor, ReadError> {
    root.accessors.get(index).ok_or_else(|| {
        err(format!(
            "{what} refers to accessor {index}, but the file has {} accessors",
            root.accessors.len()
        ))
    })
}

/// The buffer views (and so the buffers) an accessor reads, for deciding what to load.
pub fn views_of(accessor: &json::Accessor) -> impl Iterator<Item = usize> + '_ {
    let sparse = accessor
        .sparse
        .iter()
        .flat_map(|s| [s.indices.buffer_view.value(), s.values.buffer_view.value()]);
    accessor
        .buffer_view
        .map(|v| v.value())
        .into_iter()
        .chain(sparse)
}

/// How many bytes of zeros (in the accessor's own encoding) an accessor without a buffer view may
/// stand for, per byte of real input (the JSON and the loaded buffers). Such an accessor is all
/// zeros plus its sparse values, which the input holds, so a legitimate one is small next to the
/// rest of the file; `count: 100000000` in a 300-byte file is not.
pub const UNBACKED_PER_INPUT_BYTE: u64 = 8;

impl Data<'_> {
    /// The real bytes behind this asset: its JSON and every buffer loaded (a shared file once:
    /// 100 buffers naming one file do not make it 100 times the input).
    pub fn input_bytes(&self) -> u64 {
        self.root.json_bytes.saturating_add(self.buffer_bytes)
    }

    /// Refuses an accessor without a buffer view that would expand to more than the limits, or
    /// to more than the input can describe (see [`UNBACKED_PER_INPUT_BYTE`]).
    pub fn check_unbacked(&self, count: u64, size: usize, what: &str) -> Result<(), ReadError> {
        let bytes = count.saturating_mul(size as u64);
        if count > self.limits.max_triangles || bytes > self.limits.max_file_bytes {
            return Err(err(format!(
                "{what}: accessor without a buffer view declares {count} elements, over the limits: raise limits.max_triangles in the config to read it"
            )));
        }
        let input = self.input_bytes();
        if bytes > input.saturating_mul(UNBACKED_PER_INPUT_BYTE) {
            return Err(err(format!(
                "{what}: accessor without a buffer view declares {count} elements ({bytes} bytes of zeros), far more than this file's {input} bytes of JSON and buffers can describe: its data is missing (compressed by an extension meshvet cannot decode?) - fix or re-export the file"
            )));
        }
        Ok(())
    }

    /// The bytes of buffer view `index`, and its byteStride.
    fn view(&self, index: usize, what: &str) -> Result<(&[u8], Option<usize>), ReadError> {
        let root = self.root;
        let view = root.buffer_views.get(index).ok_or_else(|| {
            err(format!(
                "{what} refers to buffer view {index}, but the file has {} buffer views",
                root.buffer_views.len()
            ))
        })?;
        let b = view.buffer.value();
        let buffer: &[u8] = match self.buffers.get(b) {
            Some(Some(bytes)) => bytes,
            Some(None) => {
                return Err(err(format!(
                    "{what}: buffer {b} was not loaded (internal error: please report this file)"
                )))
            }
            None => {
                return Err(err(format!(
                    "{what}: buffer view {index} refers to buffer {b}, but the file has {} buffers",
                    root.buffers.len()
                )))
            }
        };
        let offset = view.byte_offset.map_or(0, |o| o.0);
        let length = view.byte_length.0;
        match offset.checked_add(length) {
            Some(end) if end <= buffer.len() as u64 => Ok((
                &buffer[offset as usize..end as usize],
                view.byte_stride.map(|s| s.0),
            )),
            _ => Err(err(format!(
                "{what}: buffer view {index} (offset {offset}, length {length}) runs past the end of buffer {b} ({} bytes)",
                buffer.len()
            ))),
        }
    }

    /// `count` elements of `size` bytes at `offset` in view `view`, strided as the view says.
    fn strided(
        &self,
        view: usize,
        offset: u64,
        count: usize,
        size: usize,
        use_stride: bool,
        what: &str,
    ) -> Result<Strided<'_>, ReadError> {
        let (bytes, stride) = self.view(view, what)?;
        let stride = match stride {
            Some(stride) if use_stride => stride,
            _ => size,
        };
        if stride < size {
            return Err(err(format!(
                "{what}: buffer view {view} has byteStride {stride}, smaller than the {size}-byte elements it holds"
            )));
        }
        let needed = (count as u64)
            .checked_sub(1)
            .map_or(Some(0), |last| {
                last.checked_mul(stride as u64)
                    .and_then(|n| n.checked_add(size as u64))
            })
            .and_then(|n| n.checked_add(offset));
        match needed {
            Some(needed) if needed <= bytes.len() as u64 => Ok(Strided {
                bytes: &bytes[offset as usize..],
                stride,
                size,
                count,
            }),
            _ => Err(err(format!(
                "{what}: {count} elements of {size} bytes (stride {stride}) from offset {offset} do not fit in buffer view {view} ({} bytes)",
                bytes.len()
            ))),
        }
    }

    /// Appends the elements of `accessor` to `out`, decoded by `decode`, sparse values applied.
    /// `size` is the element size in bytes. The count is checked against the data (or, for an
    /// accessor with no buffer view, against the limits and the input's size) before `out` grows.
    fn append<T: Copy + Default>(
        &self,
        accessor: &json::Accessor,
        size: usize,
        decode: impl Fn(&[u8]) -> T,
        out: &mut Vec<T>,
        what: &str,
    ) -> Result<(), ReadError> {
        let count = usize::try_from(accessor.count.0).map_err(|_| {
            err(format!(
                "{what}: accessor count {} is too large",
                accessor.count.0
            ))
        })?;
        let start = out.len();
        match accessor.buffer_view {
            Some(view) => {
                let offset = accessor.byte_offset.map_or(0, |o| o.0);
                let elements = self.strided(view.value(), offset, count, size, true, what)?;
                out.reserve(elements.count);
                out.extend((0..elements.count).map(|i| decode(elements.element(i))));
            }
            None => {
                // No data: all elements are zero (sparse values follow). Bound the allocation by
                // the limits and by the real size of the input.
                self.check_unbacked(count as u64, size, what)?;
                out.resize(start + count, T::default());
            }
        }
        if let Some(sparse) = &accessor.sparse {
            let n = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
            if n > count {
                return Err(err(format!(
                    "{what}: sparse accessor has {n} values for {count} elements"
                )));
            }
            for (at, value) in self.sparse(sparse, n, size, what)? {
                let slot = out
                    .get_mut(start + at)
                    .filter(|_| at < count)
                    .ok_or_else(|| {
                        err(format!(
                            "{what}: sparse index {at} is out of range ({count} elements)"
                        ))
                    })?;
                *slot = decode(value);
            }
        }
        Ok(())
    }

    /// The first `n` replacements of a sparse accessor whose elements are `size` bytes: for each,
    /// the index of the element it replaces (not yet checked against the count) and its bytes.
    fn sparse(
        &self,
        sparse: &json::accessor::sparse::Sparse,
        n: usize,
        size: usize,
        what: &str,
    ) -> Result<impl Iterator<Item = (usize, &[u8])>, ReadError> {
        let Checked::Valid(index_type) = sparse.indices.component_type else {
            return Err(err(format!(
                "{what}: sparse indices have an invalid componentType"
            )));
        };
        let index_type = index_type.0;
        let indices = self.strided(
            sparse.indices.buffer_view.value(),
            sparse.indices.byte_offset.0,
            n,
            index_type.size(),
            false,
            what,
        )?;
        let values = self.strided(
            sparse.values.buffer_view.value(),
            sparse.values.byte_offset.0,
            n,
            size,
            false,
            what,
        )?;
        Ok((0..n).map(move |i| {
            let at = decode_index(index_type, indices.element(i)) as usize;
            (at, values.element(i))
        }))
    }

    /// The elements of any accessor as packed bytes, `size` bytes each (strides removed, sparse
    /// values applied): for a writer that copies attributes it does not interpret.
    pub fn raw(
        &self,
        accessor: &json::Accessor,
        size: usize,
        what: &str,
    ) -> Result<Vec<u8>, ReadError> {
        let count = usize::try_from(accessor.count.0).map_err(|_| {
            err(format!(
                "{what}: accessor count {} is too large",
                accessor.count.0
            ))
        })?;
        let mut out = match accessor.buffer_view {
            Some(view) => {
                let offset = accessor.byte_offset.map_or(0, |o| o.0);
                let elements = self.strided(view.value(), offset, count, size, true, what)?;
                let mut out = Vec::with_capacity(count * size);
                for i in 0..count {
                    out.extend_from_slice(elements.element(i));
                }
                out
            }
            None => {
                self.check_unbacked(count as u64, size, what)?;
                vec![0; count * size]
            }
        };
        if let Some(sparse) = &accessor.sparse {
            let n = usize::try_from(sparse.count.0)
                .unwrap_or(usize::MAX)
                .min(count);
            for (at, value) in self.sparse(sparse, n, size, what)? {
                let slot = out.get_mut(at * size..(at + 1) * size).ok_or_else(|| {
                    err(format!(
                        "{what}: sparse index {at} is out of range ({count} elements)"
                    ))
                })?;
                slot.copy_from_slice(value);
            }
        }
        Ok(out)
    }

    /// Appends the positions of a POSITION accessor (FLOAT VEC3) to `out`, as f64.
    pub fn append_positions(
        &self,
        accessor: &json::Accessor,
        out: &mut Vec<[f64; 3]>,
        what: &str,
    ) -> Result<(), ReadError> {
        match (accessor.type_, accessor.component_type) {
            (Checked::Valid(Type::Vec3), Checked::Valid(GenericComponentType(ComponentType::F32))) => {}
            (Checked::Valid(t), Checked::Valid(GenericComponentType(c))) => {
                return Err(err(format!(
                    "{what}: POSITION accessor is {} {}, meshvet reads FLOAT VEC3 positions (integer positions are quantized, KHR_mesh_quantization, which meshvet does not decode): {}",
                    component_name(c),
                    type_name(t),
                    super::DEQUANTIZE
                )))
            }
            _ => {
                return Err(err(format!(
                    "{what}: POSITION accessor has an invalid type or componentType"
                )))
            }
        }
        self.append(accessor, 12, decode_vec3, out, what)
    }

    /// Replaces `out` with the indices of an indices accessor (UNSIGNED_BYTE/SHORT/INT SCALAR).
    pub fn read_indices(
        &self,
        accessor: &json::Accessor,
        out: &mut Vec<u32>,
        what: &str,
    ) -> Result<(), ReadError> {
        let component = match (accessor.type_, accessor.component_type) {
            (Checked::Valid(Type::Scalar), Checked::Valid(GenericComponentType(c)))
                if matches!(c, ComponentType::U8 | ComponentType::U16 | ComponentType::U32) =>
            {
                c
            }
            (Checked::Valid(t), Checked::Valid(GenericComponentType(c))) => {
                return Err(err(format!(
                    "{what}: indices accessor is {} {}, glTF allows only UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT SCALAR indices",
                    component_name(c),
                    type_name(t)
                )))
            }
            _ => {
                return Err(err(format!(
                    "{what}: indices accessor has an invalid type or componentType"
                )))
            }
        };
        out.clear();
        self.append(
            accessor,
            component.size(),
            |bytes| decode_index(component, bytes),
            out,
            what,
        )
    }
}

fn decode_vec3(b: &[u8]) -> [f64; 3] {
    let f = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]) as f64;
    [f(0), f(4), f(8)]
}

/// An unsigned index of the given component type (callers pass only U8/U16/U32 types).
fn decode_index(component: ComponentType, b: &[u8]) -> u32 {
    match component {
        ComponentType::U8 | ComponentType::I8 => b[0] as u32,
        ComponentType::U16 | ComponentType::I16 => u16::from_le_bytes([b[0], b[1]]) as u32,
        ComponentType::U32 | ComponentType::F32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}
