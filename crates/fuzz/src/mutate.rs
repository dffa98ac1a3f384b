//! Seeded mutations of a corpus: the inputs of the deterministic pass ([`crate::pass`]).
//!
//! An input is one corpus file with 1–4 mutations stacked on it, all chosen by a [`Rng`] seeded
//! with the case's seed, so `(reader, case)` always names the same bytes. The mutations are those
//! that find bugs in readers of length-prefixed and text formats:
//!
//! * bytes: bit flips; a byte set to 0, 1, 0x7F, 0x80, 0xFF or a text delimiter; a 16/32/64-bit
//!   little- or big-endian word set to 0, 1, −1, the signed extremes, 2¹⁶, 2³¹, 2⁴⁰ or a
//!   multiple of the file's length (counts and offsets); truncation at a random point; a chunk
//!   deleted, duplicated or replaced by random bytes; a splice of the head of one corpus file
//!   with the tail of another;
//! * text (any ASCII run of the file, so also PLY headers and JSON metadata in binary files): a
//!   number replaced by −1, 0, 1e308, nan, inf, a huge integer, … or given extra digits; a
//!   string's content replaced (empty, long, a path, another string of the file); a line
//!   deleted, duplicated or swapped with the next; a delimiter (`{}[],:="`) replaced or removed.
//!
//! For containers whose JSON header sits behind a length prefix (safetensors, samples files,
//! training checkpoints; [`Layout::PrefixedJson`]) half of the inputs mutate the JSON only and
//! rewrite the prefix, so that the mutations reach the header's fields instead of stopping at a
//! length mismatch.

use crate::rng::Rng;

/// How a reader's files are built, for the choice of mutations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// Text (JSON, TOML, OBJ): mostly text mutations.
    Text,
    /// Binary, possibly with a text header (PLY, EXR, `.bin` tensors): mostly byte mutations.
    Binary,
    /// Binary with a JSON header of `len_bytes` little-endian length bytes at `len_at`, the JSON
    /// starting at `json_at`.
    PrefixedJson {
        /// Offset of the length.
        len_at: usize,
        /// Width of the length (4 or 8 bytes).
        len_bytes: usize,
        /// Offset of the JSON text.
        json_at: usize,
    },
}

/// Numbers that break readers: signs, zero, extremes of every integer width, non-finite floats,
/// denormals, values that overflow f32 or every integer type.
pub const NUMBERS: &[&str] = &[
    "-1",
    "0",
    "1",
    "-0",
    "2",
    "3",
    "0.5",
    "1.5",
    "-0.5",
    "1e308",
    "-1e308",
    "1e999",
    "1e39",
    "1e-320",
    "1e-45",
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "Infinity",
    "255",
    "256",
    "65535",
    "65536",
    "1000000",
    "1e9",
    "2147483647",
    "2147483648",
    "-2147483648",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "9223372036854775808",
    "18446744073709551615",
    "18446744073709551616",
    "100000000000000000000000000000",
    "0x10",
    "1_000",
    "+1",
    "01",
    ".5",
    "5.",
    "1e",
];

/// Replacement contents of strings.
const STRINGS: &[&str] = &[
    "",
    "x",
    "..",
    "/",
    "../../../../etc/passwd",
    "view_000.exr",
    "mesh.ply",
    "nan",
    "\\u0000",
    "\\ud800",
    "é",
];

/// Structural characters of JSON and TOML.
const DELIMITERS: &[u8] = b"{}[],:=\"'.#\n";

/// Interesting byte values.
const BYTES: &[u8] = &[
    0, 1, 0x7F, 0x80, 0xFF, b' ', b'\n', b'"', b'-', b'9', b'{', b'[',
];

/// Mutates the corpus `seeds` of one reader.
pub struct Mutator<'a> {
    seeds: &'a [Vec<u8>],
    layout: Layout,
}

impl<'a> Mutator<'a> {
    /// A mutator of `seeds` (non-empty) laid out as `layout`.
    pub fn new(seeds: &'a [Vec<u8>], layout: Layout) -> Self {
        assert!(!seeds.is_empty(), "a mutator needs at least one seed");
        Mutator { seeds, layout }
    }

    /// The input of the case seeded with `seed`.
    pub fn input(&self, seed: u64) -> Vec<u8> {
        let mut rng = Rng::new(seed);
        let mut data = rng.pick(self.seeds).clone();
        if let Layout::PrefixedJson {
            len_at,
            len_bytes,
            json_at,
        } = self.layout
            && rng.chance(1, 2)
            && let Some(out) = self.mutate_prefixed(&mut rng, &data, len_at, len_bytes, json_at)
        {
            return out;
        }
        let n = 1 + rng.below(4);
        for _ in 0..n {
            let text_share = match self.layout {
                Layout::Text => 3,
                _ => 1,
            };
            if rng.chance(text_share, 4) {
                self.text_mutation(&mut rng, &mut data);
            } else {
                self.byte_mutation(&mut rng, &mut data);
            }
        }
        data
    }

    /// Text mutations of the JSON header of a prefixed container, the prefix rewritten; `None`
    /// when `data` does not hold such a header.
    fn mutate_prefixed(
        &self,
        rng: &mut Rng,
        data: &[u8],
        len_at: usize,
        len_bytes: usize,
        json_at: usize,
    ) -> Option<Vec<u8>> {
        let prefix = data.get(len_at..len_at + len_bytes)?;
        let mut word = [0u8; 8];
        word[..len_bytes].copy_from_slice(prefix);
        let len = usize::try_from(u64::from_le_bytes(word)).ok()?;
        let end = json_at.checked_add(len)?;
        let mut json = data.get(json_at..end)?.to_vec();
        for _ in 0..1 + rng.below(3) {
            self.text_mutation(rng, &mut json);
        }
        let mut out = data[..json_at].to_vec();
        let new_len = (json.len() as u64).to_le_bytes();
        out[len_at..len_at + len_bytes].copy_from_slice(&new_len[..len_bytes]);
        out.extend_from_slice(&json);
        out.extend_from_slice(&data[end..]);
        Some(out)
    }

    fn byte_mutation(&self, rng: &mut Rng, data: &mut Vec<u8>) {
        let len = data.len();
        match rng.below(9) {
            0 if len > 0 => {
                for _ in 0..1 + rng.below(4) {
                    let i = rng.below(len);
                    data[i] ^= 1 << rng.below(8);
                }
            }
            1 if len > 0 => {
                let i = rng.below(len);
                data[i] = *rng.pick(BYTES);
            }
            2 => {
                let width = *rng.pick(&[2usize, 4, 8]);
                if len >= width {
                    let i = rng.below(len - width + 1);
                    let v = interesting_word(rng, len as u64);
                    let word: Vec<u8> = if rng.chance(1, 4) {
                        v.to_be_bytes()[8 - width..].to_vec()
                    } else {
                        v.to_le_bytes()[..width].to_vec()
                    };
                    data[i..i + width].copy_from_slice(&word);
                }
            }
            3 => data.truncate(rng.below(len + 1)),
            4 if len > 0 => {
                let (a, b) = chunk(rng, len);
                data.drain(a..b);
            }
            5 if len > 0 => {
                let (a, b) = chunk(rng, len);
                let piece = data[a..b].to_vec();
                let at = rng.below(len + 1);
                data.splice(at..at, piece);
            }
            6 => {
                let at = rng.below(len + 1);
                let n = 1 + rng.below(16);
                let fill: Vec<u8> = if rng.chance(1, 2) {
                    vec![*rng.pick(BYTES); n]
                } else {
                    (0..n).map(|_| rng.next_u64() as u8).collect()
                };
                data.splice(at..at, fill);
            }
            7 => {
                let other = rng.pick(self.seeds);
                let a = rng.below(len + 1);
                let b = rng.below(other.len() + 1);
                data.truncate(a);
                data.extend_from_slice(&other[b..]);
            }
            _ => self.text_mutation(rng, data),
        }
    }

    fn text_mutation(&self, rng: &mut Rng, data: &mut Vec<u8>) {
        match rng.below(6) {
            0 | 1 => {
                let tokens = number_tokens(data);
                if tokens.is_empty() {
                    return;
                }
                let (a, b) = *rng.pick(&tokens);
                let new: Vec<u8> = if rng.chance(1, 4) {
                    // The same number with more digits, or negated.
                    let mut t = data[a..b].to_vec();
                    if rng.chance(1, 2) {
                        t.extend_from_slice(b"000000000");
                    } else {
                        t.insert(0, b'-');
                    }
                    t
                } else {
                    rng.pick(NUMBERS).as_bytes().to_vec()
                };
                data.splice(a..b, new);
            }
            2 => {
                let strings = string_tokens(data);
                if strings.is_empty() {
                    return;
                }
                let (a, b) = *rng.pick(&strings);
                let new: Vec<u8> = match rng.below(4) {
                    0 => {
                        let (c, d) = *rng.pick(&strings);
                        data[c..d].to_vec()
                    }
                    1 => vec![b'A'; 1 << (4 + rng.below(12))],
                    _ => rng.pick(STRINGS).as_bytes().to_vec(),
                };
                data.splice(a..b, new);
            }
            3 => {
                let lines = line_spans(data);
                if lines.is_empty() {
                    return;
                }
                let k = rng.below(lines.len());
                let (a, b) = lines[k];
                match rng.below(3) {
                    0 => {
                        data.drain(a..b);
                    }
                    1 => {
                        let line = data[a..b].to_vec();
                        data.splice(b..b, line);
                    }
                    _ => {
                        if let Some(&(c, d)) = lines.get(k + 1) {
                            let mut swapped = data[c..d].to_vec();
                            swapped.extend_from_slice(&data[a..b]);
                            data.splice(a..d, swapped);
                        }
                    }
                }
            }
            4 => {
                let spots: Vec<usize> = data
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| DELIMITERS.contains(c))
                    .map(|(i, _)| i)
                    .collect();
                if spots.is_empty() {
                    return;
                }
                let i = *rng.pick(&spots);
                if rng.chance(1, 3) {
                    data.remove(i);
                } else {
                    data[i] = *rng.pick(DELIMITERS);
                }
            }
            _ => {
                // Splice at line boundaries of two corpus files (keeps most of the syntax).
                let other = rng.pick(self.seeds);
                let ours = line_spans(data);
                let theirs = line_spans(other);
                if ours.is_empty() || theirs.is_empty() {
                    return;
                }
                let a = rng.pick(&ours).0;
                let b = rng.pick(&theirs).0;
                data.truncate(a);
                data.extend_from_slice(&other[b..]);
            }
        }
    }
}

/// A chunk `[a, b)` of a `len`-byte buffer (`len` > 0): mostly short, sometimes up to a quarter.
fn chunk(rng: &mut Rng, len: usize) -> (usize, usize) {
    let a = rng.below(len);
    let max = if rng.chance(1, 4) {
        (len / 4).max(1)
    } else {
        64
    };
    let b = (a + 1 + rng.below(max)).min(len);
    (a, b)
}

/// A word value for counts, sizes and offsets.
fn interesting_word(rng: &mut Rng, len: u64) -> u64 {
    match rng.below(14) {
        0 => 0,
        1 => 1,
        2 => u64::MAX,
        3 => 0x7F,
        4 => 0x80,
        5 => 0xFF,
        6 => 0x7FFF_FFFF,
        7 => 0x8000_0000,
        8 => 0xFFFF_FFFF,
        9 => 1 << 16,
        10 => 1 << 40,
        11 => i64::MAX as u64,
        12 => len.wrapping_mul(1 + rng.below(16) as u64),
        _ => rng.next_u64() >> rng.below(64),
    }
}

/// Byte ranges of the numbers in `data` (`-?digits[.digits][e[+-]digits]`), not part of a word.
pub fn number_tokens(data: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < data.len() {
        let c = data[i];
        let starts = c.is_ascii_digit()
            || (c == b'-' && data.get(i + 1).is_some_and(|d| d.is_ascii_digit()));
        let after_word = i > 0 && (data[i - 1].is_ascii_alphanumeric() || data[i - 1] == b'_');
        if !starts || after_word {
            i += 1;
            continue;
        }
        let a = i;
        i += 1;
        while i < data.len()
            && (data[i].is_ascii_digit()
                || data[i] == b'.'
                || data[i] == b'e'
                || data[i] == b'E'
                || ((data[i] == b'-' || data[i] == b'+') && matches!(data[i - 1], b'e' | b'E')))
        {
            i += 1;
        }
        out.push((a, i));
    }
    out
}

/// Byte ranges of the contents of double-quoted strings (without the quotes; escapes skipped).
pub fn string_tokens(data: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if data[i] != b'"' {
            i += 1;
            continue;
        }
        let a = i + 1;
        let mut j = a;
        while j < data.len() && data[j] != b'"' && data[j] != b'\n' {
            j += if data[j] == b'\\' { 2 } else { 1 };
        }
        if j < data.len() && data[j] == b'"' {
            out.push((a, j));
        }
        i = j + 1;
    }
    out
}

/// Byte ranges of the lines of `data`, each with its newline.
pub fn line_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut a = 0;
    for (i, &c) in data.iter().enumerate() {
        if c == b'\n' {
            out.push((a, i + 1));
            a = i + 1;
        }
    }
    if a < data.len() {
        out.push((a, data.len()));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_are_found() {
        let t = b"a = [1.5, -2e-3]\nname = \"x\\\"y\" k9 = 7";
        let nums: Vec<&[u8]> = number_tokens(t).iter().map(|&(a, b)| &t[a..b]).collect();
        assert_eq!(nums, vec![&b"1.5"[..], b"-2e-3", b"7"]);
        let strs: Vec<&[u8]> = string_tokens(t).iter().map(|&(a, b)| &t[a..b]).collect();
        assert_eq!(strs, vec![&b"x\\\"y"[..]]);
        assert_eq!(line_spans(t).len(), 2);
    }

    /// The same seed gives the same input; prefixed headers keep a consistent length.
    #[test]
    fn inputs_are_deterministic_and_prefixes_consistent() {
        let json = br#"{"n": 12, "name": "abc"}"#;
        let mut file = b"MAGIC\0\0\0".to_vec();
        file.extend_from_slice(&(json.len() as u32).to_le_bytes());
        file.extend_from_slice(json);
        file.extend_from_slice(&[1, 2, 3, 4]);
        let seeds = vec![file];
        let layout = Layout::PrefixedJson {
            len_at: 8,
            len_bytes: 4,
            json_at: 12,
        };
        let m = Mutator::new(&seeds, layout);
        let mut consistent = 0;
        for seed in 0..500 {
            let a = m.input(seed);
            assert_eq!(a, m.input(seed));
            if a.len() >= 12 {
                let len = u32::from_le_bytes(a[8..12].try_into().unwrap()) as usize;
                if a.len() == 12 + len + 4 && a.ends_with(&[1, 2, 3, 4]) {
                    consistent += 1;
                }
            }
        }
        assert!(consistent > 150, "{consistent}");
    }
}
