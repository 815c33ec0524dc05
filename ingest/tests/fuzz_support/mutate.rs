//! Seeded mutations of valid inputs: byte flips, insertions, deletions, duplicated ranges, splices of two
//! inputs, numbers replaced by extremes (text and binary), truncation, swapped/duplicated/deleted lines.
//!
//! Every case is a pure function of (base seed, reader name, case index) and the corpus, so a failing case is
//! reproduced from its seed alone.

/// The seeded generator of the `formats_*` tests (SplitMix64), shared so that one generator serves every
/// ingest test.
pub use crate::formats_common::Rng;

/// The generator of case `case` of `reader` under `seed`.
pub fn case_rng(seed: u64, reader: &str, case: u64) -> Rng {
    // FNV-1a of the reader name keeps readers' streams apart under one seed.
    let name = reader.bytes().fold(0xCBF2_9CE4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01B3));
    let mut r = Rng(seed ^ name.rotate_left(17) ^ case.wrapping_mul(0xD6E8_FEB8_6659_FD93));
    r.next_u64();
    r
}

/// Largest case, in bytes: stacked insertions and splices grow inputs; beyond this a case only costs time.
pub const MAX_CASE_LEN: usize = 1 << 16;

/// Text numbers a file should never be trusted with: zero, negatives, extremes of every integer width, float
/// overflow and subnormals, NaN and infinities in the spellings Rust's and C's parsers accept.
const TEXT_EXTREMES: &[&str] = &[
    "0",
    "-1",
    "-0",
    "1e38",
    "-1e38",
    "1e308",
    "1e309",
    "1e-320",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "infinity",
    "4294967295",
    "4294967296",
    "2147483647",
    "-2147483648",
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775807",
    "99999999999999999999999",
    "255",
    "256",
    "65535",
    "3.0",
    "0.5",
    "1e",
    "-",
    "",
];

/// Binary values for headers and bodies: counts and indices at their limits, float specials.
const BINARY_EXTREMES_32: &[u32] = &[
    0,
    1,
    0xFFFF_FFFF,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFF,
    0x100,
    0xFFFF,
    0x7FC0_0000, // f32 NaN
    0x7F80_0000, // f32 +inf
    0xFF80_0000, // f32 -inf
    0x7E96_7699, // f32 1e38
    0xBF80_0000, // f32 -1
    0x0000_0001, // f32 smallest subnormal
];

/// Text fragments that change a file's structure.
const TEXT_TOKENS: &[&str] = &[
    "\n",
    "\r\n",
    " ",
    "\t",
    "#",
    "\0",
    "{",
    "}",
    "[",
    "]",
    ",",
    "\"",
    ":",
    "null",
    "end_header\n",
    "element vertex 4294967295\n",
    "element face 4294967295\n",
    "property list uint uint vertex_indices\n",
    "property float nx\n",
    "f 1 2 3\n",
    "v 1 2 3\n",
    "mtllib x.mtl\n",
    "usemtl m\n",
    "scan a b 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n",
    "intrinsics_matrix 1 0 1 0 1 1 0 0 1\n",
    "\u{00e9}",
    "\u{fffd}",
];

/// One mutated case from `corpus` (non-empty).
pub fn mutate(rng: &mut Rng, corpus: &[Vec<u8>]) -> Vec<u8> {
    let mut data = rng.pick(corpus).clone();
    // Mostly one mutation (each case stays close to a valid input and reaches deep into the reader), sometimes
    // up to four.
    let stacked = *rng.pick(&[1usize, 1, 1, 1, 2, 2, 3, 4]);
    for _ in 0..stacked {
        mutate_once(rng, corpus, &mut data);
        if data.len() > MAX_CASE_LEN {
            data.truncate(MAX_CASE_LEN);
        }
    }
    data
}

fn mutate_once(rng: &mut Rng, corpus: &[Vec<u8>], data: &mut Vec<u8>) {
    let len = data.len();
    let at = |rng: &mut Rng| if len == 0 { 0 } else { rng.below(len + 1) };
    match rng.below(14) {
        0 if len > 0 => {
            let i = rng.below(len);
            data[i] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let i = rng.below(len);
            let random = rng.next_u64() as u8;
            data[i] = *rng.pick(&[0u8, 0xFF, 0x7F, 0x80, b'\n', b' ', b'-', b'.', b'0', b'9', b'e', random]);
        }
        2 => {
            let i = at(rng);
            let n = 1 + rng.below(16);
            let bytes: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
            data.splice(i..i, bytes);
        }
        3 => {
            let i = at(rng);
            let token = rng.pick(TEXT_TOKENS).as_bytes().to_vec();
            data.splice(i..i, token);
        }
        4 if len > 0 => {
            let a = rng.below(len);
            let n = 1 + rng.below((len - a).min(len / 4 + 1));
            data.drain(a..a + n);
        }
        5 if len > 0 => {
            let a = rng.below(len);
            let n = 1 + rng.below((len - a).min(256));
            let chunk = data[a..a + n].to_vec();
            let i = at(rng);
            data.splice(i..i, chunk);
        }
        6 => {
            // Splice: a prefix of this input and a suffix of another.
            let other = rng.pick(corpus);
            let cut_a = at(rng);
            let cut_b = if other.is_empty() { 0 } else { rng.below(other.len() + 1) };
            data.truncate(cut_a);
            data.extend_from_slice(&other[cut_b..]);
        }
        7 | 8 => replace_text_number(rng, data),
        9 if len >= 4 => {
            let v = *rng.pick(BINARY_EXTREMES_32);
            let width = *rng.pick(&[1usize, 2, 4, 4, 8]);
            let bytes: Vec<u8> = match width {
                8 => {
                    let d = *rng.pick(&[f64::NAN, f64::INFINITY, -1.0, 1e308, 0.0, u64::MAX as f64]);
                    if rng.below(2) == 0 { d.to_le_bytes().to_vec() } else { d.to_be_bytes().to_vec() }
                }
                _ if rng.below(2) == 0 => v.to_le_bytes()[..width].to_vec(),
                _ => v.to_be_bytes()[4 - width..].to_vec(),
            };
            if len >= bytes.len() {
                let i = rng.below(len - bytes.len() + 1);
                data[i..i + bytes.len()].copy_from_slice(&bytes);
            }
        }
        10 => {
            let keep = if len == 0 { 0 } else { rng.below(len) };
            data.truncate(keep);
        }
        11..=13 => mutate_lines(rng, data),
        _ => {
            if len > 0 {
                let i = rng.below(len);
                data[i] = data[i].wrapping_add(1);
            }
        }
    }
}

/// Replaces one run of number characters (`[-+0-9.eE]` containing a digit) by an extreme.
fn replace_text_number(rng: &mut Rng, data: &mut Vec<u8>) {
    let is_num = |b: u8| b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b'e' | b'E');
    let mut runs = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if is_num(data[i]) {
            let start = i;
            while i < data.len() && is_num(data[i]) {
                i += 1;
            }
            if data[start..i].iter().any(u8::is_ascii_digit) {
                runs.push((start, i));
            }
        } else {
            i += 1;
        }
    }
    if runs.is_empty() {
        return;
    }
    // Header counts come first in most formats: favour the early runs half of the time.
    let k = if rng.below(2) == 0 { rng.below(runs.len().min(16)) } else { rng.below(runs.len()) };
    let (a, b) = runs[k];
    let with = rng.pick(TEXT_EXTREMES).as_bytes().to_vec();
    data.splice(a..b, with);
}

fn mutate_lines(rng: &mut Rng, data: &mut Vec<u8>) {
    let mut lines: Vec<Vec<u8>> = data.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
    if lines.len() < 2 {
        return;
    }
    let n = lines.len();
    let (i, j) = (rng.below(n), rng.below(n));
    match rng.below(3) {
        0 => lines.swap(i, j),
        1 => {
            let l = lines[i].clone();
            lines.insert(j, l);
        }
        _ => {
            lines.remove(i);
        }
    }
    *data = lines.join(&b'\n');
}
