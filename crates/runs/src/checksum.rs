//! The checksum of shard files: XXH64 (Collet's xxHash, 64-bit, seed 0), written here from its
//! specification (`doc/xxhash_spec.md` of the xxHash project) and checked against its published
//! test vectors.
//!
//! Why this hash: shard files travel between cluster nodes and file systems, so a flipped bit or
//! a torn copy must be found before a merge uses the numbers. XXH64 finds any such damage with a
//! probability of `1 - 2^-64`, streams (a merge reads a shard once, hashing as it decodes) and
//! hashes at several GB/s (four independent lanes of 8-byte words), so that verifying costs
//! little beside reading. It is not a cryptographic hash: it guards against accidents, not
//! against a forger, who can write a matching checksum; every field of a shard is therefore
//! also checked against its scene. Written by hand (about 100 lines) rather than taken from a
//! crate, so that the file format depends on no outside release.

const P1: u64 = 0x9E37_79B1_85EB_CA87;
const P2: u64 = 0xC2B2_AE3D_27D4_EB4F;
const P3: u64 = 0x1656_67B1_9E37_79F9;
const P4: u64 = 0x85EB_CA77_C2B2_AE63;
const P5: u64 = 0x27D4_EB2F_1656_67C5;

/// A streaming XXH64 (seed 0): [`Xxh64::update`] with any split of the input gives the digest
/// of the whole input.
#[derive(Debug, Clone)]
pub struct Xxh64 {
    /// The four accumulators of the 32-byte stripes.
    acc: [u64; 4],
    /// Bytes of an unfinished stripe.
    buf: [u8; 32],
    /// How many bytes of `buf` are used.
    used: usize,
    /// Bytes hashed so far.
    total: u64,
}

impl Default for Xxh64 {
    fn default() -> Self {
        Self::new()
    }
}

fn word(b: &[u8]) -> u64 {
    let mut w = [0u8; 8];
    w.copy_from_slice(&b[..8]);
    u64::from_le_bytes(w)
}

fn round(acc: u64, input: u64) -> u64 {
    acc.wrapping_add(input.wrapping_mul(P2))
        .rotate_left(31)
        .wrapping_mul(P1)
}

fn merge_round(acc: u64, val: u64) -> u64 {
    (acc ^ round(0, val)).wrapping_mul(P1).wrapping_add(P4)
}

impl Xxh64 {
    /// Nothing hashed yet.
    pub fn new() -> Self {
        Self {
            acc: [P1.wrapping_add(P2), P2, 0, 0u64.wrapping_sub(P1)],
            buf: [0; 32],
            used: 0,
            total: 0,
        }
    }

    fn stripe(acc: &mut [u64; 4], s: &[u8]) {
        for (k, a) in acc.iter_mut().enumerate() {
            *a = round(*a, word(&s[8 * k..]));
        }
    }

    /// Hashes `data` after what was hashed before.
    pub fn update(&mut self, mut data: &[u8]) {
        self.total = self.total.wrapping_add(data.len() as u64);
        if self.used > 0 {
            let take = (32 - self.used).min(data.len());
            self.buf[self.used..self.used + take].copy_from_slice(&data[..take]);
            self.used += take;
            data = &data[take..];
            if self.used < 32 {
                return;
            }
            let buf = self.buf;
            Self::stripe(&mut self.acc, &buf);
            self.used = 0;
        }
        let mut stripes = data.chunks_exact(32);
        for s in &mut stripes {
            Self::stripe(&mut self.acc, s);
        }
        let rest = stripes.remainder();
        self.buf[..rest.len()].copy_from_slice(rest);
        self.used = rest.len();
    }

    /// The digest of everything hashed.
    pub fn digest(&self) -> u64 {
        let [a1, a2, a3, a4] = self.acc;
        let mut h = if self.total >= 32 {
            let h = a1
                .rotate_left(1)
                .wrapping_add(a2.rotate_left(7))
                .wrapping_add(a3.rotate_left(12))
                .wrapping_add(a4.rotate_left(18));
            [a1, a2, a3, a4].into_iter().fold(h, merge_round)
        } else {
            P5
        };
        h = h.wrapping_add(self.total);
        let mut rest = &self.buf[..self.used];
        while rest.len() >= 8 {
            h = (h ^ round(0, word(rest)))
                .rotate_left(27)
                .wrapping_mul(P1)
                .wrapping_add(P4);
            rest = &rest[8..];
        }
        if rest.len() >= 4 {
            let mut w = [0u8; 4];
            w.copy_from_slice(&rest[..4]);
            h = (h ^ u64::from(u32::from_le_bytes(w)).wrapping_mul(P1))
                .rotate_left(23)
                .wrapping_mul(P2)
                .wrapping_add(P3);
            rest = &rest[4..];
        }
        for &b in rest {
            h = (h ^ u64::from(b).wrapping_mul(P5))
                .rotate_left(11)
                .wrapping_mul(P1);
        }
        h ^= h >> 33;
        h = h.wrapping_mul(P2);
        h ^= h >> 29;
        h = h.wrapping_mul(P3);
        h ^ (h >> 32)
    }
}

/// The XXH64 digest (seed 0) of `data`.
pub fn xxh64(data: &[u8]) -> u64 {
    let mut h = Xxh64::new();
    h.update(data);
    h.digest()
}

/// A reader that hashes what it reads.
pub(crate) struct Hashing<R> {
    pub(crate) inner: R,
    pub(crate) hash: Xxh64,
}

impl<R: std::io::Read> std::io::Read for Hashing<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.hash.update(&buf[..n]);
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published test vectors of XXH64 with seed 0, short inputs and inputs of one and
    /// more 32-byte stripes.
    #[test]
    fn digests_are_the_published_ones() {
        assert_eq!(xxh64(b""), 0xEF46_DB37_51D8_E999);
        assert_eq!(xxh64(b"a"), 0xD24E_C4F1_A98C_6E5B);
        assert_eq!(xxh64(b"abc"), 0x44BC_2CF5_AD77_0999);
        assert_eq!(xxh64(b"Hello, World!"), 0xC49A_ACF8_080F_E47F);
        assert_eq!(xxh64(&[b'a'; 32]), 0x856E_8432_98F9_9AD7);
        assert_eq!(xxh64(&[b'a'; 33]), 0x18F3_FF0C_21E3_B24B);
    }

    /// Any split of the input into updates gives the digest of the whole.
    #[test]
    fn updates_in_pieces_give_the_whole_digest() {
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 + i / 3) as u8).collect();
        for len in [0, 3, 8, 31, 32, 33, 64, 95, 1000] {
            let whole = xxh64(&data[..len]);
            for step in [1, 5, 8, 31, 32, 33, 200] {
                let mut h = Xxh64::new();
                for piece in data[..len].chunks(step) {
                    h.update(piece);
                }
                assert_eq!(h.digest(), whole, "length {len}, pieces of {step}");
            }
        }
    }
}
