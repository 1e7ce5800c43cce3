//! NumPy `.npy` writer for complex128 and float64 arrays.
//!
//! The header is written by hand rather than through a crate: the format (NEP 1, version 1.0) is
//! a magic string, a two-byte header length and a Python dict literal, and we only ever write two
//! dtypes (`'<c16'` and `'<f8'`, little-endian complex128 and float64) in C order. Doing it here
//! costs forty lines and keeps the binary's dependency tree (and the `num-complex` version it
//! would have to agree on) small. The result loads with `numpy.load` and with any NEP-1 reader.

use speckle::phase::Complex64;

/// Magic string and version 1.0.
const MAGIC: &[u8] = b"\x93NUMPY\x01\x00";

/// NumPy pads the header so the data starts on a 64-byte boundary (since NumPy 1.14); we do too.
const ALIGN: usize = 64;

/// The `shape` tuple as Python writes it: `(3,)`, `(2, 3)`.
fn shape_tuple(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Encodes a C-order complex128 array of the given shape.
///
/// Panics if `data.len()` is not the product of `shape` (a programming error, not user input).
pub fn encode_c16(shape: &[usize], data: &[Complex64]) -> Vec<u8> {
    let mut out = header("<c16", shape, data.len(), 16);
    for c in data {
        out.extend_from_slice(&c.re.to_le_bytes());
        out.extend_from_slice(&c.im.to_le_bytes());
    }
    out
}

/// Encodes a C-order float64 array of the given shape.
///
/// Panics if `data.len()` is not the product of `shape` (a programming error, not user input).
pub fn encode_f8(shape: &[usize], data: &[f64]) -> Vec<u8> {
    let mut out = header("<f8", shape, data.len(), 8);
    for x in data {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out
}

/// The magic string and header of an array of `len` elements of `item` bytes with dtype
/// `descr`, with room reserved for the data.
fn header(descr: &str, shape: &[usize], len: usize, item: usize) -> Vec<u8> {
    assert_eq!(
        shape.iter().product::<usize>(),
        len,
        "npy: shape {shape:?} does not match {len} elements"
    );
    let mut dict = format!(
        "{{'descr': '{descr}', 'fortran_order': False, 'shape': {}, }}",
        shape_tuple(shape)
    );
    // Pad with spaces so that magic + length + dict + '\n' is a multiple of ALIGN.
    let unpadded = MAGIC.len() + 2 + dict.len() + 1;
    dict.push_str(&" ".repeat(unpadded.next_multiple_of(ALIGN) - unpadded));
    dict.push('\n');
    let header_len = u16::try_from(dict.len()).expect("npy header fits in 64 KiB");
    let mut out = Vec::with_capacity(MAGIC.len() + 2 + dict.len() + item * len);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&header_len.to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_aligned_and_describes_the_array() {
        let data = vec![Complex64::new(1.5, -2.0); 6];
        for shape in [&[6][..], &[2, 3], &[1, 2, 3]] {
            let bytes = encode_c16(shape, &data);
            assert_eq!(&bytes[..8], MAGIC);
            let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
            assert_eq!((10 + len) % ALIGN, 0);
            let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
            assert!(header.ends_with('\n'));
            assert!(header.contains(&format!("'shape': {}", shape_tuple(shape))));
            assert_eq!(bytes.len(), 10 + len + 16 * 6);
            let re = f64::from_le_bytes(bytes[10 + len..18 + len].try_into().unwrap());
            let im = f64::from_le_bytes(bytes[18 + len..26 + len].try_into().unwrap());
            assert_eq!((re, im), (1.5, -2.0));
        }
        let bytes = encode_f8(&[2, 1], &[0.25, -3.0]);
        let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + len) % ALIGN, 0);
        assert!(
            std::str::from_utf8(&bytes[10..10 + len])
                .unwrap()
                .contains("'<f8'")
        );
        assert_eq!(bytes.len(), 10 + len + 16);
        assert_eq!(bytes[10 + len + 8..], (-3.0f64).to_le_bytes());
        assert_eq!(shape_tuple(&[4]), "(4,)");
        assert_eq!(shape_tuple(&[4, 5, 6]), "(4, 5, 6)");
    }
}
