//! Hand-written PNG encoder (RGB8): CRC-32, Adler-32, zlib and deflate.
//!
//! No compression crates are allowed, so we emit one deflate block with the
//! FIXED Huffman code and a small hash-chain LZ77 matcher. Plots are mostly
//! flat colour, so long matches at distance 1 (runs) and at distance one row
//! (repeated scanlines) already compress a 900x600 plot to a few tens of kB.

/// CRC-32 (IEEE, reflected polynomial 0xEDB88320) as used by PNG chunks.
pub(super) fn crc32(data: &[u8]) -> u32 {
    let mut table = [0u32; 256];
    for (n, entry) in table.iter_mut().enumerate() {
        let mut c = n as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
        *entry = c;
    }
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc = table[((crc ^ u32::from(b)) & 0xFF) as usize] ^ (crc >> 8);
    }
    crc ^ 0xFFFF_FFFF
}

/// Adler-32 checksum that ends a zlib stream.
pub(super) fn adler32(data: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    // 5552 bytes is the largest block for which `b` cannot overflow u32.
    for chunk in data.chunks(5552) {
        for &x in chunk {
            a += u32::from(x);
            b += a;
        }
        a %= 65521;
        b %= 65521;
    }
    (b << 16) | a
}

/// Prefix each RGB row with a filter byte: type 0 (None) or 1 (Sub),
/// whichever has the smaller sum of absolute (signed) byte values.
pub(super) fn filter_rows(w: u32, h: u32, rgb: &[u8]) -> Vec<u8> {
    let stride = 3 * w as usize;
    let mut out = Vec::with_capacity((stride + 1) * h as usize);
    let mut sub = vec![0u8; stride];
    for row in rgb.chunks(stride.max(1)).take(h as usize) {
        for i in 0..stride {
            let left = if i >= 3 { row[i - 3] } else { 0 };
            sub[i] = row[i].wrapping_sub(left);
        }
        let cost = |r: &[u8]| {
            r.iter()
                .map(|&b| u64::from((b as i8).unsigned_abs()))
                .sum::<u64>()
        };
        if cost(&sub) < cost(row) {
            out.push(1);
            out.extend_from_slice(&sub);
        } else {
            out.push(0);
            out.extend_from_slice(row);
        }
    }
    out
}

/// Encode an RGB8 image (`rgb.len() == 3*w*h`) as a complete PNG file.
pub(super) fn encode(w: u32, h: u32, rgb: &[u8]) -> Vec<u8> {
    let mut png = vec![0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1A, b'\n'];
    let mut ihdr = Vec::with_capacity(13);
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]); // 8-bit, truecolour, deflate, filter 0, no interlace
    chunk(&mut png, b"IHDR", &ihdr);
    chunk(&mut png, b"IDAT", &zlib(&filter_rows(w, h, rgb)));
    chunk(&mut png, b"IEND", &[]);
    png
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let start = out.len();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let crc = crc32(&out[start..]);
    out.extend_from_slice(&crc.to_be_bytes());
}

/// zlib stream: 2-byte header (deflate, 32 KiB window), deflate data, Adler-32.
pub(super) fn zlib(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    out.extend_from_slice(&deflate(data));
    out.extend_from_slice(&adler32(data).to_be_bytes());
    out
}

/// LSB-first bit writer, as deflate requires.
struct Bits {
    out: Vec<u8>,
    acc: u64,
    n: u32,
}

impl Bits {
    fn put(&mut self, v: u32, n: u32) {
        self.acc |= u64::from(v) << self.n;
        self.n += n;
        while self.n >= 8 {
            self.out.push(self.acc as u8);
            self.acc >>= 8;
            self.n -= 8;
        }
    }
    /// Huffman codes are defined MSB-first, so they go out bit-reversed.
    fn put_code(&mut self, code: u32, len: u32) {
        self.put(code.reverse_bits() >> (32 - len), len);
    }
    /// Fixed-Huffman literal/length symbol (RFC 1951, 3.2.6).
    fn put_sym(&mut self, sym: u32) {
        match sym {
            0..=143 => self.put_code(0x30 + sym, 8),
            144..=255 => self.put_code(0x190 + sym - 144, 9),
            256..=279 => self.put_code(sym - 256, 7),
            _ => self.put_code(0xC0 + sym - 280, 8),
        }
    }
}

const LEN_BASE: [u32; 29] = [
    3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59, 67, 83, 99, 115, 131,
    163, 195, 227, 258,
];
const LEN_EXTRA: [u32; 29] = [
    0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0,
];
const DIST_BASE: [u32; 30] = [
    1, 2, 3, 4, 5, 7, 9, 13, 17, 25, 33, 49, 65, 97, 129, 193, 257, 385, 513, 769, 1025, 1537,
    2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577,
];
const DIST_EXTRA: [u32; 30] = [
    0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13,
    13,
];

const WINDOW: usize = 32768;
const MIN_MATCH: usize = 3;
const MAX_MATCH: usize = 258;
const HASH_BITS: u32 = 15;
const MAX_CHAIN: usize = 64;
const NONE: usize = usize::MAX;

fn hash3(d: &[u8], i: usize) -> usize {
    let v = u32::from(d[i]) | u32::from(d[i + 1]) << 8 | u32::from(d[i + 2]) << 16;
    (v.wrapping_mul(0x9E37_79B1) >> (32 - HASH_BITS)) as usize
}

/// Raw deflate stream: a single final block with fixed Huffman codes.
pub(super) fn deflate(data: &[u8]) -> Vec<u8> {
    let mut bits = Bits {
        out: Vec::with_capacity(data.len() / 16 + 64),
        acc: 0,
        n: 0,
    };
    bits.put(1, 1); // BFINAL
    bits.put(1, 2); // BTYPE = 01, fixed Huffman
    let mut head = vec![NONE; 1 << HASH_BITS];
    let mut prev = vec![NONE; WINDOW];
    let mut i = 0;
    while i < data.len() {
        let (len, dist) = longest_match(data, i, &head, &prev);
        if len >= MIN_MATCH {
            let li = LEN_BASE.partition_point(|&b| b <= len as u32) - 1;
            bits.put_sym(257 + li as u32);
            bits.put(len as u32 - LEN_BASE[li], LEN_EXTRA[li]);
            let di = DIST_BASE.partition_point(|&b| b <= dist as u32) - 1;
            bits.put_code(di as u32, 5);
            bits.put(dist as u32 - DIST_BASE[di], DIST_EXTRA[di]);
            for k in i..i + len {
                insert(data, k, &mut head, &mut prev);
            }
            i += len;
        } else {
            bits.put_sym(u32::from(data[i]));
            insert(data, i, &mut head, &mut prev);
            i += 1;
        }
    }
    bits.put_sym(256); // end of block
    bits.put(0, 7); // flush the last partial byte
    bits.out
}

/// Record position `i` in the hash chains.
fn insert(data: &[u8], i: usize, head: &mut [usize], prev: &mut [usize]) {
    if i + MIN_MATCH <= data.len() {
        let h = hash3(data, i);
        prev[i % WINDOW] = head[h];
        head[h] = i;
    }
}

/// Best earlier match for position `i` along the hash chain: (length, distance).
fn longest_match(data: &[u8], i: usize, head: &[usize], prev: &[usize]) -> (usize, usize) {
    let max = MAX_MATCH.min(data.len() - i);
    if max < MIN_MATCH {
        return (0, 0);
    }
    let (mut best_len, mut best_dist) = (0, 0);
    let mut cand = head[hash3(data, i)];
    let mut chain = 0;
    while cand != NONE && cand < i && i - cand <= WINDOW && chain < MAX_CHAIN {
        if best_len == 0 || data[cand + best_len] == data[i + best_len] {
            let len = data[cand..cand + max]
                .iter()
                .zip(&data[i..i + max])
                .take_while(|(a, b)| a == b)
                .count();
            if len > best_len {
                (best_len, best_dist) = (len, i - cand);
                if len == max {
                    break;
                }
            }
        }
        let next = prev[cand % WINDOW];
        if next != NONE && next >= cand {
            break;
        }
        cand = next;
        chain += 1;
    }
    (best_len, best_dist)
}
