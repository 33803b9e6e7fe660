//! Reading 2-D NumPy arrays (`.npy`, format 1.0–3.0): the visibility buffers and masks that
//! `diff`, `report` and the reference cache read. Every array is returned row-major (C order),
//! whatever the file's `fortran_order` (what `np.save` writes for a transposed array); the
//! declared shape is checked against the bytes the file holds before anything is allocated for
//! it, and each side is bounded like an image side (1..=[`MAX_RESOLUTION`]).
//!
//! [`MAX_RESOLUTION`]: crate::scenario::validate::MAX_RESOLUTION

use std::path::Path;

use crate::error::InputError;
use crate::scenario::validate::MAX_RESOLUTION;

/// A 2-D array read from a `.npy` file: `height` rows of `width` values, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Array2<T> {
    pub width: u32,
    pub height: u32,
    pub data: Vec<T>,
}

/// Reads `path` as a 2-D array of `T` (`f32` for NumPy's `float32`, `u8` for `uint8`; `kind`
/// names that type in errors, e.g. "float32"). Errors, each naming the file: not a regular
/// file, larger than the memory limit ([`crate::util::input::read_bytes`]), not a `.npy`
/// header, another dtype, not 2-D, a side of 0 or over [`MAX_RESOLUTION`], or fewer data bytes
/// than the shape needs.
pub fn read_2d<T: npyz::Deserialize + Copy>(
    path: &Path,
    what: &str,
    kind: &str,
) -> Result<Array2<T>, InputError> {
    parse_2d(
        &crate::util::input::read_bytes(path, what)?,
        path,
        what,
        kind,
    )
}

/// The deepest nesting of brackets a `.npy` header may have: a 2-D array of a plain dtype (the
/// only kind read) has a dict holding a shape tuple, 2 levels; a structured dtype's list of
/// tuples adds 2 (it is then refused by its dtype).
const MAX_HEADER_NESTING: usize = 4;

/// Refuses a header nested deeper than [`MAX_HEADER_NESTING`] before the header parser sees it:
/// its Python-literal grammar takes time exponential in the depth (found by the `npy` fuzz
/// target: 60 unclosed `(` took over 40 s, 15 nested `{` over 30 s). The header is the text after the 10- or 12-byte
/// preamble, up to its newline.
fn check_header_nesting(bytes: &[u8]) -> Result<(), String> {
    let start = match bytes.get(6) {
        Some(1) => 10,
        _ => 12,
    };
    let header = bytes.get(start..).unwrap_or_default();
    let end = header
        .iter()
        .position(|&b| b == b'\n')
        .unwrap_or(header.len());
    let mut depth = 0usize;
    let mut deepest = 0;
    for &b in &header[..end] {
        match b {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => depth = depth.saturating_sub(1),
            _ => {}
        }
        deepest = deepest.max(depth);
    }
    if deepest > MAX_HEADER_NESTING {
        return Err(format!(
            "not a .npy file: its header nests {deepest} brackets deep (at most \
             {MAX_HEADER_NESTING})"
        ));
    }
    Ok(())
}

/// [`read_2d`] of the bytes of a `.npy` file; `path` names it in errors.
pub fn parse_2d<T: npyz::Deserialize + Copy>(
    bytes: &[u8],
    path: &Path,
    what: &str,
    kind: &str,
) -> Result<Array2<T>, InputError> {
    let bad = |m: String| InputError::file(path, format!("{what}: {m}"));
    check_header_nesting(bytes).map_err(&bad)?;
    let npy = npyz::NpyFile::new(bytes).map_err(|e| bad(format!("not a .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    let [rows, cols] = shape[..] else {
        return Err(bad(format!("expected a 2-D array, found shape {shape:?}")));
    };
    let side = 1..=MAX_RESOLUTION as u64;
    if !side.contains(&rows) || !side.contains(&cols) {
        return Err(bad(format!(
            "shape ({rows}, {cols}): each side must be in 1..={MAX_RESOLUTION}"
        )));
    }
    let dtype = npy.dtype();
    let fortran = npy.order() == npyz::Order::Fortran;
    // The data's size from the header, checked against the file before the reader allocates
    // a vector of the declared length.
    let held = npy.into_inner().len() as u64;
    let need = (dtype.num_bytes()).map(|b| b as u64 * rows * cols);
    if let Some(need) = need.filter(|&n| n > held) {
        return Err(bad(format!(
            "shape ({rows}, {cols}) of dtype {} needs {need} bytes of data, the file holds {held}",
            dtype.descr()
        )));
    }
    let npy = npyz::NpyFile::new(bytes).map_err(|e| bad(e.to_string()))?;
    let reader = npy.data::<T>().map_err(|_| {
        bad(format!(
            "expected a {kind} array, found dtype {}",
            dtype.descr()
        ))
    })?;
    let stored: Vec<T> = reader
        .collect::<std::io::Result<_>>()
        .map_err(|e| bad(e.to_string()))?;
    let (rows, cols) = (rows as usize, cols as usize);
    let data = if fortran {
        // Column-major: element (r, c) is at c * rows + r.
        (0..rows * cols)
            .map(|i| stored[(i % cols) * rows + i / cols])
            .collect()
    } else {
        stored
    };
    Ok(Array2 {
        width: cols as u32,
        height: rows as u32,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A header of deeply nested brackets (exponential for the header's parser) is refused
    /// at once, naming the file.
    #[test]
    fn a_deeply_nested_header_is_refused() {
        let mut header = b"{'descr': '".to_vec();
        header.extend(std::iter::repeat_n(b'(', 60));
        header.extend(b"f8', 'fortran_order': False, 'shape': (1, 1), }\n");
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend((header.len() as u16).to_le_bytes());
        bytes.extend(&header);
        bytes.extend(0f64.to_le_bytes());
        let start = std::time::Instant::now();
        let e = parse_2d::<f32>(&bytes, Path::new("v.npy"), "visibility array", "float32")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("v.npy") && e.contains("brackets deep (at most 4)"),
            "{e}"
        );
        assert!(start.elapsed().as_secs() < 5);
    }
}
