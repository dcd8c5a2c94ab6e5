//! The fuzzer's inputs: seeded mutations of a corpus, and purely random bytes.
//!
//! Every input is a function of `(seed, target, index)` and the pool it mutates (the target's
//! seed corpus, then the inputs kept for reaching a new outcome, in the order they were kept),
//! so a run with `--iterations N` makes the same inputs on every machine, and a run of one
//! target makes the same inputs as that target's part of a run of all of them.
//!
//! An input is, one time in [`RANDOM_ONE_IN`], purely random (bytes, or tokens of the target's
//! dictionary); otherwise a pool entry with 1 to 8 stacked [`Mutation`]s, then, one time in two,
//! the target's checksum repair (so a mutation reaches past the checksum that would refuse it).

use ferroslam_sim::synth::rng::SplitMix64;

/// One input in this many is purely random rather than a mutated pool entry.
pub const RANDOM_ONE_IN: u64 = 16;

/// What the mutator knows of a target: the longest input worth making, the tokens its format is
/// made of, and how to repair the checksums a mutation broke.
#[derive(Debug, Clone, Copy)]
pub struct Shape {
    /// Longest input made, bytes (a mutation that grows past it is cut there).
    pub max_len: usize,
    /// Tokens inserted or written over by [`Mutation::Token`] (keys, keywords, magic numbers,
    /// separators, numbers parsers get wrong).
    pub dictionary: &'static [&'static [u8]],
    /// Recomputes the format's checksums (and counts) so a mutated input passes them.
    pub repair: Option<fn(&mut Vec<u8>)>,
    /// Whether the input is text: [`TEXT_TOKENS`] (numbers and separators parsers get wrong)
    /// are tokens too.
    pub text: bool,
}

/// Tokens of every text format: numbers at and past the edges of `f64`, `f32`, `u32` and
/// integer syntax, and separators, line ends, comments, a NUL and a byte-order mark.
pub const TEXT_TOKENS: &[&[u8]] = &[
    b"nan",
    b"NaN",
    b"inf",
    b"-inf",
    b"infinity",
    b"1e308",
    b"1e309",
    b"-1e309",
    b"1e-320",
    b"-0",
    b"-0.0",
    b"0",
    b"0.0",
    b"4294967295",
    b"4294967296",
    b"-1",
    b"18446744073709551616",
    b"9007199254740993",
    b"0x10",
    b"1_000",
    b"+1",
    b".5",
    b"5.",
    b"1e",
    b"3.4028236e38",
    b" ",
    b"\t",
    b"\n",
    b"\r\n",
    b"\r",
    b"#",
    b"# ",
    b"\0",
    b"\xEF\xBB\xBF",
];

/// The random stream of one input.
#[derive(Debug, Clone)]
pub struct Rng(SplitMix64);

impl Rng {
    /// The stream of input `index` of target `target` under `seed`.
    pub fn for_input(seed: u64, target: &str, index: u64) -> Self {
        Self(SplitMix64::keyed(seed, name_key(target), index))
    }

    /// A stream started at `seed` (for the frames target's pixels).
    pub fn new(seed: u64) -> Self {
        Self(SplitMix64::new(seed))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `0..n`; 0 when `n` is 0.
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next_u64() % n as u64) as usize }
    }

    /// True one time in `n`.
    pub fn one_in(&mut self, n: u64) -> bool {
        n == 0 || self.next_u64().is_multiple_of(n)
    }

    /// A random byte.
    pub fn byte(&mut self) -> u8 {
        self.next_u64() as u8
    }

    /// One of `items` (`None` when there are none).
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> Option<&'a T> {
        items.get(self.below(items.len()))
    }
}

/// FNV-1a of a target's name: the key that separates the targets' random streams.
fn name_key(name: &str) -> u64 {
    name.bytes()
        .fold(0xCBF2_9CE4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01B3))
}

/// One way of changing an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mutation {
    /// Flip 1 to 4 random bits.
    FlipBits,
    /// Replace 1 to 4 bytes by random ones.
    ReplaceBytes,
    /// Insert 1 to 16 bytes (random, or one byte repeated).
    InsertBytes,
    /// Delete a run of 1 to 64 bytes.
    DeleteBytes,
    /// Cut the input at a random length.
    Truncate,
    /// The input's head joined to another pool entry's tail.
    Splice,
    /// Write (or insert) an edge value: 0, 0xFF, i16/u16/u32 extremes (both byte orders), f32
    /// and f64 NaN, infinities, extremes, subnormals and -0; written over an aligned field one
    /// time in two.
    Interesting,
    /// Copy a run of the input over another place in it (repeated structures).
    CopyChunk,
    /// Write (or insert) a token of the target's dictionary.
    Token,
}

/// Every mutation, in the order [`Mutation::random`] numbers them.
pub const MUTATIONS: [Mutation; 9] = [
    Mutation::FlipBits,
    Mutation::ReplaceBytes,
    Mutation::InsertBytes,
    Mutation::DeleteBytes,
    Mutation::Truncate,
    Mutation::Splice,
    Mutation::Interesting,
    Mutation::CopyChunk,
    Mutation::Token,
];

impl Mutation {
    /// A random mutation.
    pub fn random(rng: &mut Rng) -> Self {
        MUTATIONS[rng.below(MUTATIONS.len())]
    }

    /// Applies the mutation to `data`; `other` is the pool entry a splice takes its tail from.
    pub fn apply(self, rng: &mut Rng, data: &mut Vec<u8>, other: &[u8], shape: &Shape) {
        match self {
            Self::FlipBits => {
                for _ in 0..1 + rng.below(4) {
                    let at = rng.below(data.len());
                    if let Some(b) = data.get_mut(at) {
                        *b ^= 1 << rng.below(8);
                    }
                }
            }
            Self::ReplaceBytes => {
                for _ in 0..1 + rng.below(4) {
                    let at = rng.below(data.len());
                    let value = rng.byte();
                    if let Some(b) = data.get_mut(at) {
                        *b = value;
                    }
                }
            }
            Self::InsertBytes => {
                let n = 1 + rng.below(16);
                let repeated = rng.one_in(2).then(|| rng.byte());
                let bytes: Vec<u8> =
                    (0..n).map(|_| repeated.unwrap_or_else(|| rng.byte())).collect();
                insert(rng, data, &bytes);
            }
            Self::DeleteBytes => {
                let at = rng.below(data.len());
                let n = (1 + rng.below(64)).min(data.len() - at.min(data.len()));
                data.drain(at..at + n);
            }
            Self::Truncate => {
                let len = rng.below(data.len() + 1);
                data.truncate(len);
            }
            Self::Splice => {
                let head = rng.below(data.len() + 1);
                let tail = rng.below(other.len() + 1);
                data.truncate(head);
                data.extend_from_slice(other.get(tail..).unwrap_or(&[]));
            }
            Self::Interesting => {
                let value = interesting_value(rng);
                if rng.one_in(2) {
                    put(rng, data, &value);
                } else {
                    // Over a field of its own width: binary formats align their fields.
                    let at = rng.below(data.len() + 1);
                    overwrite(data, at - at % value.len().max(1), &value);
                }
            }
            Self::CopyChunk => {
                if data.is_empty() {
                    return;
                }
                let from = rng.below(data.len());
                let n = 1 + rng.below((data.len() - from).min(256));
                let chunk = data.get(from..from + n).unwrap_or(&[]).to_vec();
                put(rng, data, &chunk);
            }
            Self::Token => {
                if let Some(token) = pick_token(rng, shape) {
                    put(rng, data, token);
                }
            }
        }
    }
}

/// A token of the target's dictionary, or, for text, one of [`TEXT_TOKENS`] one time in two.
fn pick_token(rng: &mut Rng, shape: &Shape) -> Option<&'static [u8]> {
    let tokens = if shape.text && (shape.dictionary.is_empty() || rng.one_in(2)) {
        TEXT_TOKENS
    } else {
        shape.dictionary
    };
    rng.pick(tokens).copied()
}

/// Writes `bytes` over `data` at a random place (growing it at the end if need be), or inserts
/// them there, one time in two each.
fn put(rng: &mut Rng, data: &mut Vec<u8>, bytes: &[u8]) {
    if rng.one_in(2) {
        insert(rng, data, bytes);
        return;
    }
    let at = rng.below(data.len() + 1);
    overwrite(data, at, bytes);
}

/// Writes `bytes` over `data` from `at`, growing it at the end if need be.
fn overwrite(data: &mut Vec<u8>, at: usize, bytes: &[u8]) {
    let end = at + bytes.len();
    if data.len() < end {
        data.resize(end, 0);
    }
    if let Some(dst) = data.get_mut(at..end) {
        dst.copy_from_slice(bytes);
    }
}

/// Inserts `bytes` at a random place of `data`.
fn insert(rng: &mut Rng, data: &mut Vec<u8>, bytes: &[u8]) {
    let at = rng.below(data.len() + 1);
    data.splice(at..at, bytes.iter().copied());
}

/// An edge value as bytes (see [`Mutation::Interesting`]).
fn interesting_value(rng: &mut Rng) -> Vec<u8> {
    let little = !rng.one_in(4);
    let order = |b: Vec<u8>| if little { b } else { b.into_iter().rev().collect() };
    match rng.below(5) {
        0 => vec![*rng.pick(&[0u8, 1, 0x7F, 0x80, 0xFF]).unwrap_or(&0)],
        1 => {
            let v = *rng
                .pick(&[0u16, 1, 0x7F, 0x80, 0xFF, 0x100, 0x7FFF, 0x8000, 0xFFFF])
                .unwrap_or(&0);
            order(v.to_le_bytes().to_vec())
        }
        2 => {
            let v = *rng
                .pick(&[0u32, 1, 0x7FFF_FFFF, 0x8000_0000, u32::MAX, 0x1_0000, u32::MAX - 1])
                .unwrap_or(&0);
            order(v.to_le_bytes().to_vec())
        }
        3 => {
            let v = *rng
                .pick(&[
                    f32::NAN,
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                    f32::MAX,
                    f32::MIN,
                    f32::MIN_POSITIVE,
                    f32::from_bits(1),
                    -0.0,
                    1.0,
                    -1.0,
                ])
                .unwrap_or(&0.0);
            order(v.to_le_bytes().to_vec())
        }
        _ => {
            let v = *rng
                .pick(&[
                    f64::NAN,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::MAX,
                    f64::MIN_POSITIVE,
                    f64::from_bits(1),
                    -0.0,
                    1e300,
                ])
                .unwrap_or(&0.0);
            order(v.to_le_bytes().to_vec())
        }
    }
}

/// An input for a target of shape `shape`, drawn from `rng` (see the module documentation):
/// purely random, or a mutated entry of `pool` (random when the pool is empty).
pub fn make_input(rng: &mut Rng, pool: &[Vec<u8>], shape: &Shape) -> Vec<u8> {
    if pool.is_empty() || rng.one_in(RANDOM_ONE_IN) {
        return random_input(rng, shape);
    }
    let mut data = rng.pick(pool).cloned().unwrap_or_default();
    let stacked = if rng.one_in(4) { 1 + rng.below(8) } else { 1 + rng.below(3) };
    for _ in 0..stacked {
        let other = rng.pick(pool).map_or(&[][..], Vec::as_slice);
        Mutation::random(rng).apply(rng, &mut data, other, shape);
    }
    data.truncate(shape.max_len);
    if let Some(repair) = shape.repair
        && rng.one_in(2)
    {
        repair(&mut data);
        data.truncate(shape.max_len);
    }
    data
}

/// Purely random bytes (any length up to the target's longest), or, one time in two when the
/// target has a dictionary, a run of its tokens and random bytes.
fn random_input(rng: &mut Rng, shape: &Shape) -> Vec<u8> {
    // Mostly short: a parser's first checks are where short inputs go.
    let cap = if rng.one_in(4) { shape.max_len } else { shape.max_len.min(256) };
    let len = rng.below(cap + 1);
    if (shape.dictionary.is_empty() && !shape.text) || rng.one_in(2) {
        return (0..len).map(|_| rng.byte()).collect();
    }
    let mut data = Vec::new();
    while data.len() < len {
        match pick_token(rng, shape) {
            Some(token) if !rng.one_in(4) => data.extend_from_slice(token),
            _ => data.push(rng.byte()),
        }
    }
    data
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHAPE: Shape =
        Shape { max_len: 4096, dictionary: &[b"fx", b" = ", b"nan"], repair: None, text: true };

    fn inputs(seed: u64, target: &str, pool: &[Vec<u8>]) -> Vec<Vec<u8>> {
        (0..500).map(|i| make_input(&mut Rng::for_input(seed, target, i), pool, &SHAPE)).collect()
    }

    #[test]
    fn same_seed_same_inputs_and_another_seed_or_target_others() {
        let pool = vec![b"fx = 525.0\nfy = 525.0\n".to_vec(), vec![0u8; 64], (0..=255).collect()];
        let a = inputs(7, "calibration", &pool);
        assert_eq!(a, inputs(7, "calibration", &pool));
        let other_seed = inputs(8, "calibration", &pool);
        let other_target = inputs(7, "lists", &pool);
        let differ = |b: &[Vec<u8>]| a.iter().zip(b).filter(|(x, y)| x != y).count();
        assert!(differ(&other_seed) > 400, "{}", differ(&other_seed));
        assert!(differ(&other_target) > 400, "{}", differ(&other_target));
    }

    #[test]
    fn inputs_vary_stay_within_bounds_and_include_random_ones() {
        let pool = vec![b"0.000000 rgb/frame-000000.png\n".to_vec()];
        let all = inputs(1, "lists", &pool);
        assert!(all.iter().all(|i| i.len() <= SHAPE.max_len));
        let distinct: std::collections::BTreeSet<_> = all.iter().collect();
        assert!(distinct.len() > 400, "{} distinct inputs of 500", distinct.len());
        assert!(all.iter().any(|i| i.is_empty() || !i.starts_with(b"0")));
    }

    #[test]
    fn every_mutation_is_deterministic_and_safe_on_any_input() {
        for m in MUTATIONS {
            for data in [Vec::new(), vec![0xAB], (0..100).collect::<Vec<u8>>()] {
                let run = || {
                    let mut rng = Rng::new(3);
                    let mut d = data.clone();
                    m.apply(&mut rng, &mut d, b"other entry", &SHAPE);
                    d
                };
                assert_eq!(run(), run(), "{m:?}");
            }
        }
    }
}
