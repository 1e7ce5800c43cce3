//! The NumPy `.npy` format, in one place: the writer of the arrays every command outputs
//! (complex128 and float64, C order) and the reader of real arrays (voxel grids).
//!
//! The header is written by hand rather than through a crate: the format (NEP 1, version 1.0) is
//! a magic string, a two-byte header length and a Python dict literal, and we only ever write two
//! dtypes (`'<c16'` and `'<f8'`, little-endian complex128 and float64) in C order. Doing it here
//! costs forty lines and keeps the dependency tree (and the `num-complex` version it would have
//! to agree on) small. The result loads with `numpy.load` and with any NEP-1 reader.

use num_complex::Complex64;

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

/// Encodes a C-order int64 array of the given shape.
///
/// Panics if `data.len()` is not the product of `shape` (a programming error, not user input).
pub fn encode_i8(shape: &[usize], data: &[i64]) -> Vec<u8> {
    let mut out = header("<i8", shape, data.len(), 8);
    for x in data {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out
}

/// The magic string and header of a C-order complex128 array of the given shape: what
/// [`encode_c16`] writes before the data (for a file written in pieces, by a streaming merge).
pub fn c16_header(shape: &[usize]) -> Vec<u8> {
    header_with("<c16", shape, 0)
}

/// The magic string and header of an array of `len` elements of `item` bytes with dtype
/// `descr`, with room reserved for the data.
fn header(descr: &str, shape: &[usize], len: usize, item: usize) -> Vec<u8> {
    assert_eq!(
        shape.iter().product::<usize>(),
        len,
        "npy: shape {shape:?} does not match {len} elements"
    );
    header_with(descr, shape, item * len)
}

/// The magic string and header of an array of `shape` with dtype `descr`, with room for
/// `reserve` more bytes.
fn header_with(descr: &str, shape: &[usize], reserve: usize) -> Vec<u8> {
    let mut dict = format!(
        "{{'descr': '{descr}', 'fortran_order': False, 'shape': {}, }}",
        shape_tuple(shape)
    );
    // Pad with spaces so that magic + length + dict + '\n' is a multiple of ALIGN.
    let unpadded = MAGIC.len() + 2 + dict.len() + 1;
    dict.push_str(&" ".repeat(unpadded.next_multiple_of(ALIGN) - unpadded));
    dict.push('\n');
    let header_len = u16::try_from(dict.len()).expect("npy header fits in 64 KiB");
    let mut out = Vec::with_capacity(MAGIC.len() + 2 + dict.len() + reserve);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&header_len.to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out
}

/// A real array read from a `.npy` file, converted to `f64`, in C order (x slowest).
#[derive(Debug, Clone, PartialEq)]
pub struct RealArray {
    /// The shape.
    pub shape: Vec<usize>,
    /// The values in C order.
    pub data: Vec<f64>,
    /// Whether the stored dtype was an integer type (material ids must be).
    pub integer: bool,
}

/// Largest array [`decode_real`] accepts (elements): 2^28, 2 GiB of `f64`.
pub const MAX_READ_ELEMENTS: usize = 1 << 28;

/// Decodes a `.npy` file (versions 1-3) holding a real array: little- or big-endian floats
/// (`f4`, `f8`), signed or unsigned integers (1-8 bytes) or booleans, in C or Fortran order
/// (converted to C order). Errors say what is wrong in words.
pub fn decode_real(bytes: &[u8]) -> Result<RealArray, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy file (the magic string \\x93NUMPY is missing)".into());
    }
    let (len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(format!("unsupported .npy version {v}")),
    };
    let header = bytes
        .get(start..start + len)
        .ok_or("the .npy header is truncated")?;
    let header = std::str::from_utf8(header).map_err(|_| "the .npy header is not text")?;
    let value = |key: &str| -> Result<&str, String> {
        let at = header
            .find(&format!("'{key}'"))
            .ok_or(format!("the .npy header has no '{key}'"))?;
        let rest = header[at + key.len() + 2..].trim_start();
        Ok(rest.strip_prefix(':').unwrap_or(rest).trim_start())
    };
    let descr = value("descr")?;
    let descr = descr
        .strip_prefix('\'')
        .and_then(|d| d.split('\'').next())
        .ok_or("the .npy dtype is not a simple type")?;
    let fortran = value("fortran_order")?.starts_with("True");
    let shape_text = value("shape")?;
    let shape_text = shape_text
        .strip_prefix('(')
        .and_then(|t| t.split(')').next())
        .ok_or("the .npy shape is malformed")?;
    let shape = shape_text
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<usize>()
                .map_err(|_| format!("bad .npy shape entry {t:?}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let n = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .filter(|&n| n <= MAX_READ_ELEMENTS)
        .ok_or(format!(
            "the array of shape {shape:?} is larger than {MAX_READ_ELEMENTS} elements"
        ))?;
    let (order, kind, size) = {
        let mut c = descr.chars();
        let order = c.next().ok_or("empty .npy dtype")?;
        let kind = c.next().ok_or("bad .npy dtype")?;
        let size: usize = c
            .as_str()
            .parse()
            .map_err(|_| format!("bad .npy dtype {descr:?}"))?;
        (order, kind, size)
    };
    let big = match order {
        '<' | '|' | '=' => false,
        '>' => true,
        _ => return Err(format!("bad .npy dtype {descr:?}")),
    };
    let convert: fn(&[u8], bool) -> f64 = match (kind, size) {
        ('f', 8) => |b, big| {
            let a: [u8; 8] = b.try_into().expect("8 bytes");
            if big {
                f64::from_be_bytes(a)
            } else {
                f64::from_le_bytes(a)
            }
        },
        ('f', 4) => |b, big| {
            let a: [u8; 4] = b.try_into().expect("4 bytes");
            f64::from(if big {
                f32::from_be_bytes(a)
            } else {
                f32::from_le_bytes(a)
            })
        },
        ('i', 1..=8) => |b, big| {
            let mut a = [0u8; 8];
            let neg = if big { b[0] } else { b[b.len() - 1] } & 0x80 != 0;
            a.fill(if neg { 0xff } else { 0 });
            for (k, &x) in b.iter().enumerate() {
                a[if big { b.len() - 1 - k } else { k }] = x;
            }
            i64::from_le_bytes(a) as f64
        },
        ('u' | 'b', 1..=8) => |b, big| {
            let mut a = [0u8; 8];
            for (k, &x) in b.iter().enumerate() {
                a[if big { b.len() - 1 - k } else { k }] = x;
            }
            u64::from_le_bytes(a) as f64
        },
        _ => {
            return Err(format!(
                "unsupported .npy dtype {descr:?}: use a real float or integer array"
            ));
        }
    };
    if !matches!(
        (kind, size),
        ('f', 4 | 8) | ('i' | 'u', 1 | 2 | 4 | 8) | ('b', 1)
    ) {
        return Err(format!("unsupported .npy dtype {descr:?}"));
    }
    let body = &bytes[start + len..];
    if body.len() < n * size {
        return Err(format!(
            "the .npy data is truncated: {} bytes for {n} elements of {size} bytes",
            body.len()
        ));
    }
    let values: Vec<f64> = body[..n * size]
        .chunks_exact(size)
        .map(|b| convert(b, big))
        .collect();
    let data = if fortran && shape.len() > 1 {
        // Fortran order: the first index is fastest. Re-index into C order.
        let mut out = vec![0.0; n];
        let mut idx = vec![0usize; shape.len()];
        for v in &values {
            let mut c = 0;
            for (d, &i) in idx.iter().enumerate() {
                c = c * shape[d] + i;
            }
            out[c] = *v;
            for (d, i) in idx.iter_mut().enumerate() {
                *i += 1;
                if *i < shape[d] {
                    break;
                }
                *i = 0;
            }
        }
        out
    } else {
        values
    };
    Ok(RealArray {
        shape,
        data,
        integer: kind != 'f',
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_what_numpy_writes() {
        // Our own float64 writer round-trips.
        let data: Vec<f64> = (0..24).map(|i| i as f64 * 0.5 - 3.0).collect();
        let a = decode_real(&encode_f8(&[2, 3, 4], &data)).unwrap();
        assert_eq!(
            (a.shape.clone(), a.data.clone(), a.integer),
            (vec![2, 3, 4], data, false)
        );
        // Hand-made headers: int16 little-endian C order, uint8, big-endian int32, Fortran f4.
        let make = |descr: &str, fortran: bool, shape: &str, body: &[u8]| {
            let dict = format!(
                "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}\n",
                if fortran { "True" } else { "False" }
            );
            let mut v = b"\x93NUMPY\x01\x00".to_vec();
            v.extend_from_slice(&(dict.len() as u16).to_le_bytes());
            v.extend_from_slice(dict.as_bytes());
            v.extend_from_slice(body);
            v
        };
        let i2: Vec<u8> = [-2i16, 7, 300]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let a = decode_real(&make("<i2", false, "(3,)", &i2)).unwrap();
        assert_eq!((a.data, a.integer), (vec![-2.0, 7.0, 300.0], true));
        let a = decode_real(&make("|u1", false, "(2, 1)", &[0, 255])).unwrap();
        assert_eq!(a.data, vec![0.0, 255.0]);
        let be: Vec<u8> = [-5i32, 9].iter().flat_map(|x| x.to_be_bytes()).collect();
        assert_eq!(
            decode_real(&make(">i4", false, "(2,)", &be)).unwrap().data,
            vec![-5.0, 9.0]
        );
        // Fortran order (2, 3): memory holds columns; C order reads rows.
        let f4: Vec<u8> = [0.0f32, 3.0, 1.0, 4.0, 2.0, 5.0]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let a = decode_real(&make("<f4", true, "(2, 3)", &f4)).unwrap();
        assert_eq!(a.data, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        // Errors in words.
        assert!(decode_real(b"hello").unwrap_err().contains("not a .npy"));
        assert!(
            decode_real(&make("<c16", false, "(1,)", &[0; 16]))
                .unwrap_err()
                .contains("dtype")
        );
        assert!(
            decode_real(&make("<f8", false, "(4,)", &[0; 16]))
                .unwrap_err()
                .contains("truncated")
        );
    }

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
