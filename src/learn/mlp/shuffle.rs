//! The per-epoch permutation of the training rows: Fisher–Yates from the identity with the
//! crate's bounded draws (`crate::rng::below`) on the stream `(seed, "mlp/shuffle")`.
//!
//! One permutation of 83 000 rows per epoch costs as much as a sixth of the epoch when every draw
//! goes through `rand_chacha`'s four-block generator, so [`Draws`] produces the same ChaCha8
//! keystream sixteen blocks at a time with the crate's vector builds, then leaves the generator
//! exactly where the same draws would have. Tests pin it word for word to `rand_chacha`.

use super::lanes::{Lanes, Words, multiversion};
use crate::rng::Rng;
use rand::RngCore;

/// Something that yields the crate generator's `next_u64` sequence.
pub(crate) trait U64s {
    /// The next 64 bits.
    fn next(&mut self) -> u64;
}

impl U64s for Rng {
    #[inline]
    fn next(&mut self) -> u64 {
        self.next_u64()
    }
}

/// Exactly [`crate::rng::below`] (same values, same draws consumed) on any word source.
#[inline]
pub(crate) fn below_fast(rng: &mut impl U64s, n: u64) -> u64 {
    crate::rng::bounded(|| rng.next(), n)
}

/// Blocks of 16 words generated at a time.
const BLOCKS: usize = 16;

/// `rand_chacha::ChaCha8Rng`'s output, generated in bulk: on creation it reads the generator's
/// key, stream and position; on drop it moves the generator past the words it handed out, so
/// the generator continues as if it had produced them itself.
pub(crate) struct Draws<'a> {
    rng: &'a mut Rng,
    /// The ChaCha input block of the next refill (constants, key, counter, stream).
    input: [u32; 16],
    /// Word `w` of block `b` at `buf[w * BLOCKS + b]` (the generator's lane layout).
    buf: [u32; 16 * BLOCKS],
    /// Next word of `buf` to hand out, in stream order (`16 · BLOCKS` when used up).
    pos: usize,
    /// Stream position, in words, of `buf`'s first word.
    base: u128,
}

impl<'a> Draws<'a> {
    /// Continues `rng`'s stream from where it stands.
    pub(crate) fn new(rng: &'a mut Rng) -> Draws<'a> {
        let (seed, stream, word) = (rng.get_seed(), rng.get_stream(), rng.get_word_pos());
        let mut input = [0u32; 16];
        input[..4].copy_from_slice(&[0x6170_7865, 0x3320_646e, 0x7962_2d32, 0x6b20_6574]);
        for (k, c) in input[4..12].iter_mut().zip(seed.chunks_exact(4)) {
            *k = u32::from_le_bytes(c.try_into().unwrap());
        }
        let block = (word / 16) as u64;
        input[12..16].copy_from_slice(&[block as u32, (block >> 32) as u32, stream as u32, (stream >> 32) as u32]);
        let mut d = Draws { rng, input, buf: [0; 16 * BLOCKS], pos: 0, base: word - word % 16 };
        d.refill();
        d.pos = (word % 16) as usize;
        d
    }

    /// Generates the next `BLOCKS` blocks (the buffer must be used up, or not yet filled).
    fn refill(&mut self) {
        if self.pos > 0 {
            self.base += self.pos as u128;
        }
        chacha8(crate::learn::cpu::mlp(), &self.input, &mut self.buf);
        let block = (self.input[12] as u64 | (self.input[13] as u64) << 32).wrapping_add(BLOCKS as u64);
        self.input[12] = block as u32;
        self.input[13] = (block >> 32) as u32;
        self.pos = 0;
    }

    #[inline]
    fn word(&mut self) -> u32 {
        if self.pos == 16 * BLOCKS {
            self.refill();
        }
        let w = self.buf[(self.pos % 16) * BLOCKS + self.pos / 16];
        self.pos += 1;
        w
    }
}

impl U64s for Draws<'_> {
    /// As `BlockRng::next_u64`: the low half is the earlier word.
    #[inline]
    fn next(&mut self) -> u64 {
        let p = self.pos;
        if p.is_multiple_of(2) && p < 16 * BLOCKS {
            // Both words in one block: word p % 16 and the next, of block p / 16.
            let at = (p % 16) * BLOCKS + p / 16;
            self.pos = p + 2;
            return self.buf[at] as u64 | (self.buf[at + BLOCKS] as u64) << 32;
        }
        let lo = self.word() as u64;
        lo | (self.word() as u64) << 32
    }
}

impl Drop for Draws<'_> {
    fn drop(&mut self) {
        self.rng.set_word_pos(self.base + self.pos as u128);
    }
}

/// `BLOCKS` consecutive ChaCha8 blocks from `input` (its counter incremented per block), word
/// `w` of block `b` into `out[w * BLOCKS + b]`: RFC 7539's quarter round, 4 double rounds, the
/// input added back. Integer operations only, so every build gives the same words.
#[inline(always)]
fn chacha8_body<L: Lanes>(input: &[u32; 16], out: &mut [u32; 16 * BLOCKS]) {
    chacha8_words::<L::Words>(input, out);
}

#[inline(always)]
fn chacha8_words<W: Words>(input: &[u32; 16], out: &mut [u32; 16 * BLOCKS]) {
    let mut init = [W::load(&[0; BLOCKS]); 16];
    for (i, &w) in init.iter_mut().zip(input) {
        *i = W::load(&[w; BLOCKS]);
    }
    let start = input[12] as u64 | (input[13] as u64) << 32;
    let (mut lo, mut hi) = ([0u32; BLOCKS], [0u32; BLOCKS]);
    for b in 0..BLOCKS {
        let c = start.wrapping_add(b as u64);
        (lo[b], hi[b]) = (c as u32, (c >> 32) as u32);
    }
    (init[12], init[13]) = (W::load(&lo), W::load(&hi));
    let mut x = init;
    #[inline(always)]
    fn quarter<W: Words>(x: &mut [W; 16], a: usize, b: usize, c: usize, d: usize) {
        x[a] = x[a].add(x[b]);
        x[d] = x[d].xor_rotl::<16>(x[a]);
        x[c] = x[c].add(x[d]);
        x[b] = x[b].xor_rotl::<12>(x[c]);
        x[a] = x[a].add(x[b]);
        x[d] = x[d].xor_rotl::<8>(x[a]);
        x[c] = x[c].add(x[d]);
        x[b] = x[b].xor_rotl::<7>(x[c]);
    }
    for _ in 0..4 {
        quarter(&mut x, 0, 4, 8, 12);
        quarter(&mut x, 1, 5, 9, 13);
        quarter(&mut x, 2, 6, 10, 14);
        quarter(&mut x, 3, 7, 11, 15);
        quarter(&mut x, 0, 5, 10, 15);
        quarter(&mut x, 1, 6, 11, 12);
        quarter(&mut x, 2, 7, 8, 13);
        quarter(&mut x, 3, 4, 9, 14);
    }
    for ((xw, iw), o) in x.iter().zip(&init).zip(out.chunks_exact_mut(BLOCKS)) {
        xw.add(*iw).store(o.try_into().unwrap());
    }
}

multiversion! {
    /// `BLOCKS` ChaCha8 blocks (see `chacha8_body`).
    fn chacha8(input: &[u32; 16], out: &mut [u32; 16 * BLOCKS]) -> () = chacha8_body
}

/// A uniform permutation of `0..perm.len()` into `perm`, whatever it held: Fisher–Yates from the
/// identity, swapping position `i` (from the top down) with `below(i + 1)`.
pub(crate) fn shuffle(perm: &mut [u32], rng: &mut Rng) {
    let mut rng = Draws::new(rng);
    for (i, p) in perm.iter_mut().enumerate() {
        *p = i as u32;
    }
    // Swap partners are drawn (and prefetched) a block ahead of their swaps: the random accesses
    // into a permutation larger than L1 would otherwise stall every swap. Same draws, same swaps.
    const BLOCK: usize = 32;
    let mut partner = [0usize; BLOCK];
    let mut top = perm.len();
    while top > 1 {
        let n = (top - 1).min(BLOCK);
        for (k, j) in partner[..n].iter_mut().enumerate() {
            *j = below_fast(&mut rng, (top - k) as u64) as usize;
            prefetch(perm.as_ptr().wrapping_add(*j));
        }
        for (k, &j) in partner[..n].iter().enumerate() {
            perm.swap(top - 1 - k, j);
        }
        top -= n;
    }
}

/// A cache hint for `p` (no effect on results).
#[inline(always)]
fn prefetch(p: *const u32) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults, whatever the address.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>(p.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
