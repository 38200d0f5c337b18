//! Bounds checks that make the `gltf` crate's accessor reader safe to call.
//!
//! Owns: deciding, before any element is read or any vector is allocated,
//! that an accessor's declared layout (component type, element type, count,
//! byte offsets, stride, sparse substitution) fits inside the buffer data
//! that was actually loaded.
//!
//! Invariant: after [`check`] succeeds for an accessor, `gltf`'s
//! `accessor::Iter` built from it yields exactly `count` elements without
//! panicking, and `count` is backed by real bytes (or bounded by
//! [`MAX_UNBACKED_ELEMENTS`] for a sparse accessor without a buffer view), so
//! collecting it cannot allocate more than a small multiple of the input.

use gltf::accessor::{DataType, Dimensions};

/// Largest element count accepted for a sparse accessor without a buffer
/// view: such elements are implicit zeros, so no bytes back the count.
pub(super) const MAX_UNBACKED_ELEMENTS: usize = 1 << 24;

/// What a use of an accessor requires of it.
pub(super) struct Expect {
    /// Human-readable role, for messages ("POSITION", "indices", "TEXCOORD_0").
    pub role: String,
    pub types: &'static [DataType],
    pub dimensions: Dimensions,
}

/// Checks `accessor` against `expect` and the loaded `buffers`. The error is a
/// message without the mesh/primitive prefix.
pub(super) fn check(
    accessor: &gltf::Accessor<'_>,
    expect: &Expect,
    buffers: &[gltf::buffer::Data],
) -> Result<(), String> {
    let index = accessor.index();
    let role = &expect.role;
    let data_type = accessor.data_type();
    if !expect.types.contains(&data_type) || accessor.dimensions() != expect.dimensions {
        return Err(format!(
            "{role} accessor {index} has type {:?} {:?}, expected {:?} of {:?}",
            accessor.dimensions(),
            data_type,
            expect.dimensions,
            expect.types
        ));
    }
    let count = accessor.count();
    if count == 0 {
        return Err(format!("{role} accessor {index} is empty (count 0)"));
    }
    let element = data_type.size() * expect.dimensions.multiplicity();
    match (accessor.view(), accessor.sparse()) {
        (Some(view), _) => {
            let stride = view.stride().unwrap_or(element);
            check_range(
                &view,
                accessor.offset(),
                count,
                element,
                stride,
                buffers,
                &format!("{role} accessor {index}"),
            )?;
        }
        (None, Some(_)) if count <= MAX_UNBACKED_ELEMENTS => {}
        (None, Some(_)) => {
            return Err(format!(
                "{role} accessor {index} declares {count} elements without a buffer view \
                 (limit {MAX_UNBACKED_ELEMENTS})"
            ));
        }
        (None, None) => {
            return Err(format!(
                "{role} accessor {index} has neither a buffer view nor sparse data"
            ));
        }
    }
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        let what = format!("{role} accessor {index} sparse");
        if n == 0 || n > count {
            return Err(format!(
                "{what} count {n} is not in 1..={count} (the accessor count)"
            ));
        }
        let indices = sparse.indices();
        let index_size = indices.index_type().size();
        let view = indices.view();
        let stride = view.stride().unwrap_or(index_size);
        check_range(
            &view,
            indices.offset(),
            n,
            index_size,
            stride,
            buffers,
            &format!("{what} indices"),
        )?;
        // In range (just checked): each index must be below the accessor's
        // count and above the one before it, as the specification says.
        let data = &buffers[view.buffer().index()][view.offset() + indices.offset()..];
        let mut previous = None;
        for k in 0..n {
            let bytes = &data[k * stride..k * stride + index_size];
            let i = bytes
                .iter()
                .rev()
                .fold(0usize, |v, &b| (v << 8) | usize::from(b));
            if i >= count || previous.is_some_and(|p| i <= p) {
                return Err(format!(
                    "{what} index {k} is {i}: sparse indices must increase and stay below the \
                     accessor count {count}"
                ));
            }
            previous = Some(i);
        }
        let values = sparse.values();
        let view = values.view();
        check_range(
            &view,
            values.offset(),
            n,
            element,
            view.stride().unwrap_or(element),
            buffers,
            &format!("{what} values"),
        )?;
    }
    Ok(())
}

/// `count` elements of `element` bytes, `stride` apart, starting `offset`
/// bytes into `view`, must lie inside the view, and the view inside its
/// loaded buffer. All arithmetic is checked: declared sizes are untrusted.
fn check_range(
    view: &gltf::buffer::View<'_>,
    offset: usize,
    count: usize,
    element: usize,
    stride: usize,
    buffers: &[gltf::buffer::Data],
    what: &str,
) -> Result<(), String> {
    if stride < element {
        return Err(format!(
            "{what}: byte stride {stride} is smaller than the element size {element}"
        ));
    }
    let view_end = view.offset().checked_add(view.length());
    // The buffer's declared length bounds its views, whatever was loaded.
    let available = buffers
        .get(view.buffer().index())
        .map_or(0, |b| b.len())
        .min(view.buffer().length());
    match view_end {
        Some(end) if end <= available => {}
        _ => {
            return Err(format!(
                "{what}: buffer view {} (offset {}, length {}) exceeds buffer {} ({available} bytes)",
                view.index(),
                view.offset(),
                view.length(),
                view.buffer().index()
            ));
        }
    }
    let end = stride
        .checked_mul(count - 1)
        .and_then(|x| x.checked_add(element))
        .and_then(|x| x.checked_add(offset));
    match end {
        Some(end) if end <= view.length() => Ok(()),
        _ => Err(format!(
            "{what}: {count} elements of {element} bytes (stride {stride}, offset {offset}) \
             exceed buffer view {} ({} bytes)",
            view.index(),
            view.length()
        )),
    }
}
