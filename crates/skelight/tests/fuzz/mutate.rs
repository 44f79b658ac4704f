//! A seeded byte and text mutator (stable Rust, no dependencies): bit flips, interesting
//! bytes and integers, range deletion, duplication and splicing, and for text formats
//! number, line and nesting edits that keep the file close to parseable.

/// SplitMix64: small, fast, and the same sequence on every platform.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in 0..n (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.below(xs.len())]
    }
}

const NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1",
    "-0",
    "1e30",
    "-1e30",
    "1e-30",
    "nan",
    "inf",
    "-inf",
    "NaN",
    "3.4e38",
    "1e39",
    "4294967295",
    "4294967296",
    "2147483647",
    "-2147483648",
    "99999999999",
    "18446744073709551615",
    "0.5",
    "1e12",
    "65536",
];
const BYTES: &[u8] = &[0, 1, 0x7f, 0x80, 0xff, b'<', b'>', b'"', b'/', b'\n', b'0', b'9', b'-', b'.', b'{', b'['];
const INTS: &[u64] = &[0, 1, 0xff, 0xffff, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, u64::MAX, 1 << 40, 100_000_000];

/// One to four mutations of a seed chosen from `seeds` (with text edits when `text`).
pub fn mutate(rng: &mut Rng, seeds: &[Vec<u8>], text: bool) -> Vec<u8> {
    let mut d = rng.pick(seeds).clone();
    for _ in 0..1 + rng.below(4) {
        let choices = if text { 12 } else { 8 };
        match rng.below(choices) {
            0 => flip_bit(rng, &mut d),
            1 => set_byte(rng, &mut d),
            2 => delete_range(rng, &mut d),
            3 => duplicate_range(rng, &mut d),
            4 => set_int(rng, &mut d),
            5 => splice(rng, &mut d, seeds),
            6 => {
                let at = rng.below(d.len() + 1);
                d.truncate(at);
            }
            7 => {
                let at = rng.below(d.len() + 1);
                let junk: Vec<u8> = (0..1 + rng.below(8)).map(|_| rng.next() as u8).collect();
                d.splice(at..at, junk);
            }
            8 | 9 => replace_number(rng, &mut d),
            10 => edit_lines(rng, &mut d),
            _ => nest(rng, &mut d),
        }
    }
    d
}

fn range(rng: &mut Rng, len: usize) -> (usize, usize) {
    let a = rng.below(len + 1);
    let long = rng.below(4) == 0;
    let n = 1 + rng.below(if long { 256 } else { 16 });
    (a, (a + n).min(len))
}

fn flip_bit(rng: &mut Rng, d: &mut [u8]) {
    if !d.is_empty() {
        let i = rng.below(d.len());
        d[i] ^= 1 << rng.below(8);
    }
}

fn set_byte(rng: &mut Rng, d: &mut [u8]) {
    if !d.is_empty() {
        let i = rng.below(d.len());
        d[i] = *rng.pick(BYTES);
    }
}

fn delete_range(rng: &mut Rng, d: &mut Vec<u8>) {
    let (a, b) = range(rng, d.len());
    d.drain(a..b);
}

fn duplicate_range(rng: &mut Rng, d: &mut Vec<u8>) {
    let (a, b) = range(rng, d.len());
    let chunk = d[a..b].to_vec();
    let at = rng.below(d.len() + 1);
    d.splice(at..at, chunk);
}

/// Overwrites 1, 2, 4 or 8 bytes with an interesting little- or big-endian integer.
fn set_int(rng: &mut Rng, d: &mut [u8]) {
    let width = [1, 2, 4, 8][rng.below(4)];
    if d.len() < width {
        return;
    }
    let at = rng.below(d.len() - width + 1);
    let v = *rng.pick(INTS) ^ if rng.below(2) == 0 { 0 } else { rng.next() & 0xff };
    let bytes = if rng.below(2) == 0 { v.to_le_bytes() } else { v.to_be_bytes() };
    let src = if rng.below(2) == 0 { &bytes[..width] } else { &bytes[8 - width..] };
    d[at..at + width].copy_from_slice(src);
}

fn splice(rng: &mut Rng, d: &mut Vec<u8>, seeds: &[Vec<u8>]) {
    let other = rng.pick(seeds);
    let (a, b) = range(rng, other.len());
    let at = rng.below(d.len() + 1);
    d.splice(at..at, other[a..b].iter().copied());
}

/// Replaces a run of digits (with its sign, point and exponent) by an interesting number.
fn replace_number(rng: &mut Rng, d: &mut Vec<u8>) {
    let starts: Vec<usize> =
        (0..d.len()).filter(|&i| d[i].is_ascii_digit() && (i == 0 || !d[i - 1].is_ascii_digit())).collect();
    if starts.is_empty() {
        return;
    }
    let a = *rng.pick(&starts);
    let mut b = a;
    while b < d.len() && (d[b].is_ascii_digit() || matches!(d[b], b'.' | b'e' | b'E' | b'-' | b'+')) {
        b += 1;
    }
    let a = if a > 0 && d[a - 1] == b'-' { a - 1 } else { a };
    d.splice(a..b, rng.pick(NUMBERS).bytes());
}

/// Deletes, duplicates or swaps whole lines.
fn edit_lines(rng: &mut Rng, d: &mut Vec<u8>) {
    let mut lines: Vec<Vec<u8>> = d.split(|&c| c == b'\n').map(<[u8]>::to_vec).collect();
    let (i, j) = (rng.below(lines.len()), rng.below(lines.len()));
    match rng.below(3) {
        0 => {
            lines.remove(i);
        }
        1 => {
            let l = lines[i].clone();
            let many = rng.below(8) == 0;
            for _ in 0..1 + rng.below(if many { 1000 } else { 3 }) {
                lines.insert(j, l.clone());
            }
        }
        _ => lines.swap(i, j),
    }
    *d = lines.join(&b'\n');
}

/// Repeats a tag-, bracket- or brace-opening run many times: deep nesting.
fn nest(rng: &mut Rng, d: &mut Vec<u8>) {
    let opens: Vec<usize> = (0..d.len()).filter(|&i| matches!(d[i], b'<' | b'[' | b'{')).collect();
    if opens.is_empty() {
        return;
    }
    let a = *rng.pick(&opens);
    let end = d[a..].iter().position(|&c| matches!(c, b'>' | b'"' | b',')).map_or(d.len(), |k| a + k + 1);
    let chunk = d[a..end.min(a + 64)].to_vec();
    let times = [2, 50, 5000][rng.below(3)];
    let rep: Vec<u8> = chunk.iter().copied().cycle().take(chunk.len() * times).collect();
    d.splice(a..a, rep);
}
