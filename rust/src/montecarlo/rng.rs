//! Pseudo-random numbers for the Monte Carlo, with no dependency: SplitMix64 (seeding),
//! xoshiro256++ (the streams), exact Bernoulli tests on uniform integers and standard normals by
//! the ziggurat method.
//!
//! Everything here is deterministic and platform independent: the same seed gives the same
//! numbers on every machine.

use std::sync::OnceLock;

/// The golden-ratio increment of SplitMix64.
const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// The SplitMix64 output function (Stafford's Mix13): a bijection of `u64` with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// SplitMix64 (Steele, Lea and Flood), the generator recommended for seeding xoshiro.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SplitMix64 {
    /// The counter, advanced by the golden gamma each step.
    state: u64,
}

impl SplitMix64 {
    /// A generator started at `seed` (any value, zero included).
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// The generator of sub-stream `index` of `seed`, e.g. one per block of Monte Carlo runs.
    ///
    /// Its start is the hash `mix64(mix64(seed) ^ mix64(index + γ))`, so neighbouring seeds and
    /// indices give unrelated streams; two sub-streams overlap only if their 64-bit starts fall
    /// within the few thousand outputs each one uses, which has probability ~2^-50 per pair.
    pub fn stream(seed: u64, index: u64) -> Self {
        SplitMix64::new(mix64(mix64(seed) ^ mix64(index.wrapping_add(GOLDEN_GAMMA))))
    }

    /// The next output.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN_GAMMA);
        mix64(self.state)
    }
}

/// One xoshiro256++ step of four generators at once, state transposed (`s[k][i]` is word k of
/// generator i), so the lanes map onto vector registers. Returns each generator's output.
#[inline(always)]
pub fn xoshiro256pp_x4(s: &mut [[u64; 4]; 4]) -> [u64; 4] {
    let [s0, s1, s2, s3] = s;
    let mut out = [0u64; 4];
    for i in 0..4 {
        out[i] = s0[i]
            .wrapping_add(s3[i])
            .rotate_left(23)
            .wrapping_add(s0[i]);
        let t = s1[i] << 17;
        s2[i] ^= s0[i];
        s3[i] ^= s1[i];
        s1[i] ^= s2[i];
        s0[i] ^= s3[i];
        s2[i] ^= t;
        s3[i] = s3[i].rotate_left(45);
    }
    out
}

/// [`xoshiro256pp_x4`] on AVX2 registers: `s` holds the four state words, each over the four
/// generators. Returns the four outputs.
///
/// # Safety
/// Compiled for AVX2: safe to call from other functions compiled for AVX2; elsewhere the call is
/// `unsafe`, and the CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2")]
pub fn xoshiro256pp_x4_avx2(s: &mut [std::arch::x86_64::__m256i; 4]) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let [s0, s1, s2, s3] = *s;
    let sum = _mm256_add_epi64(s0, s3);
    let rot = _mm256_or_si256(_mm256_slli_epi64::<23>(sum), _mm256_srli_epi64::<41>(sum));
    let out = _mm256_add_epi64(rot, s0);
    let t = _mm256_slli_epi64::<17>(s1);
    let s2 = _mm256_xor_si256(s2, s0);
    let s3 = _mm256_xor_si256(s3, s1);
    let s1 = _mm256_xor_si256(s1, s2);
    let s0 = _mm256_xor_si256(s0, s3);
    let s3 = _mm256_or_si256(_mm256_slli_epi64::<45>(s3), _mm256_srli_epi64::<19>(s3));
    *s = [s0, s1, _mm256_xor_si256(s2, t), s3];
    out
}

/// xoshiro256++ 1.0 (Blackman and Vigna): period 2^256 - 1, passes BigCrush in all bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Xoshiro256pp {
    /// The four state words (never all zero).
    s: [u64; 4],
}

impl Xoshiro256pp {
    /// Seeds the four state words with four SplitMix64 outputs. SplitMix64 outputs of distinct
    /// states are distinct, so at most one word is zero and the state is never the forbidden
    /// all-zero one.
    pub fn from_splitmix(sm: &mut SplitMix64) -> Self {
        let s = [sm.next_u64(), sm.next_u64(), sm.next_u64(), sm.next_u64()];
        Xoshiro256pp { s }
    }

    /// `from_splitmix(&mut SplitMix64::new(seed))`.
    pub fn seed_from_u64(seed: u64) -> Self {
        Self::from_splitmix(&mut SplitMix64::new(seed))
    }

    /// The raw state words (for lane-parallel kernels that step many generators at once).
    pub fn state(&self) -> [u64; 4] {
        self.s
    }

    /// The next output: 64 uniform bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// A uniform double in [0, 1) with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        u53_to_unit(self.next_u64() >> 11)
    }

    /// A uniform double in (0, 1] with 53 random bits (safe to take the logarithm of).
    #[inline]
    pub fn next_f64_open0(&mut self) -> f64 {
        u53_to_unit((self.next_u64() >> 11) + 1)
    }

    /// A standard normal N(0, 1) by the ziggurat ([`normal`]).
    #[inline]
    pub fn normal(&mut self) -> f64 {
        normal(self)
    }
}

/// `x · 2^-53` for `x < 2^53` (exact).
#[inline]
fn u53_to_unit(x: u64) -> f64 {
    x as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The threshold T with P(U < T) = T / 2^64 for U uniform on u64: T = ⌊p 2^64⌋, so the test
/// `U < T` is a Bernoulli(p) draw exact to 2^-64. `p` is clamped to [0, 1]; p = 1 gives
/// u64::MAX (probability 1 - 2^-64), callers that need certainty must not draw.
pub fn bernoulli_threshold(p: f64) -> u64 {
    if p.is_nan() || p <= 0.0 {
        0
    } else if p >= 1.0 {
        u64::MAX
    } else {
        // p · 2^64 is exact (a power-of-two scaling); `as` truncates towards zero and saturates.
        (p * 18_446_744_073_709_551_616.0) as u64
    }
}

// ---------------------------------------------------------------------------------------------
// Ziggurat (Marsaglia and Tsang 2000, in Doornik's 2005 "ZIGNOR" form with 128 layers).

/// Layers of the ziggurat.
const ZIG_LAYERS: usize = 128;
/// Start of the right tail.
const ZIG_R: f64 = 3.442_619_855_899;
/// Area of each layer (and of the bottom layer together with the tail).
const ZIG_V: f64 = 9.912_563_035_262_17e-3;

/// The ziggurat's tables.
struct Ziggurat {
    /// Right edges x_0 > x_1 = R > ... > x_127 > x_128 = 0; x_0 = V / f(R) is the bottom layer's
    /// pseudo-width.
    x: [f64; ZIG_LAYERS + 1],
    /// x_{i+1} / x_i: the fraction of layer i lying wholly under the density.
    ratio: [f64; ZIG_LAYERS],
}

/// The tables, built on first use.
fn ziggurat() -> &'static Ziggurat {
    static TABLES: OnceLock<Ziggurat> = OnceLock::new();
    TABLES.get_or_init(|| {
        let mut x = [0.0; ZIG_LAYERS + 1];
        let mut f = (-0.5 * ZIG_R * ZIG_R).exp();
        x[0] = ZIG_V / f;
        x[1] = ZIG_R;
        for i in 2..ZIG_LAYERS {
            x[i] = (-2.0 * (ZIG_V / x[i - 1] + f).ln()).sqrt();
            f = (-0.5 * x[i] * x[i]).exp();
        }
        x[ZIG_LAYERS] = 0.0;
        let mut ratio = [0.0; ZIG_LAYERS];
        for i in 0..ZIG_LAYERS {
            ratio[i] = x[i + 1] / x[i];
        }
        Ziggurat { x, ratio }
    })
}

/// A standard normal draw by the ziggurat: one 64-bit draw (7 bits pick the layer, 53 bits the
/// abscissa) in ~98.8% of cases, an exact rejection step otherwise. Exact up to the 53-bit
/// resolution of the uniforms.
pub fn normal(rng: &mut Xoshiro256pp) -> f64 {
    NormalSampler::new().draw(rng)
}

/// [`normal`] with the ziggurat's tables fetched once, for loops that draw many normals: the
/// common case (one 64-bit draw, one compare) inlines into the caller, the rest stays out of
/// line. Draws exactly what [`normal`] draws.
#[derive(Clone, Copy)]
pub struct NormalSampler(&'static Ziggurat);

impl Default for NormalSampler {
    fn default() -> Self {
        Self::new()
    }
}

impl NormalSampler {
    /// A sampler on the ziggurat's tables (built once per process).
    pub fn new() -> Self {
        NormalSampler(ziggurat())
    }

    /// A standard normal N(0, 1) drawn from `rng`, as [`normal`] draws it.
    #[inline(always)]
    pub fn draw(self, rng: &mut Xoshiro256pp) -> f64 {
        match ziggurat_attempt(self.0, rng) {
            Ok(x) => x,
            Err(bits) => normal_retry(self.0, rng, bits),
        }
    }
}

/// One ziggurat attempt's rectangle test: the normal if the point lies in its layer's
/// rectangle, else the attempt's random bits (for the wedge or tail test).
#[inline(always)]
fn ziggurat_attempt(z: &Ziggurat, rng: &mut Xoshiro256pp) -> Result<f64, u64> {
    let bits = rng.next_u64();
    let i = (bits & (ZIG_LAYERS as u64 - 1)) as usize;
    let u = 2.0 * u53_to_unit(bits >> 11) - 1.0; // [-1, 1)
    if u.abs() < z.ratio[i] {
        Ok(u * z.x[i])
    } else {
        Err(bits)
    }
}

/// The rest of an attempt that missed its rectangle (`bits` are that attempt's), then whole
/// attempts until one is accepted.
#[cold]
#[inline(never)]
fn normal_retry(z: &Ziggurat, rng: &mut Xoshiro256pp, mut bits: u64) -> f64 {
    loop {
        let i = (bits & (ZIG_LAYERS as u64 - 1)) as usize;
        let u = 2.0 * u53_to_unit(bits >> 11) - 1.0;
        if i == 0 {
            return normal_tail(rng, u < 0.0);
        }
        // Wedge of layer i: accept (x, y) with y uniform on [f(x_i), f(x_{i+1})] iff y < f(x),
        // written relative to f(x) as in Doornik's implementation.
        let xx = u * z.x[i];
        let f0 = (-0.5 * (z.x[i] * z.x[i] - xx * xx)).exp();
        let f1 = (-0.5 * (z.x[i + 1] * z.x[i + 1] - xx * xx)).exp();
        if f1 + rng.next_f64() * (f0 - f1) < 1.0 {
            return xx;
        }
        match ziggurat_attempt(z, rng) {
            Ok(x) => return x,
            Err(b) => bits = b,
        }
    }
}

/// Marsaglia's exact tail method for |Z| > R.
fn normal_tail(rng: &mut Xoshiro256pp, negative: bool) -> f64 {
    loop {
        let x = rng.next_f64_open0().ln() / ZIG_R; // <= 0
        let y = rng.next_f64_open0().ln();
        if -2.0 * y >= x * x {
            return if negative { x - ZIG_R } else { ZIG_R - x };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference outputs of the published C implementations (splitmix64.c, xoshiro256plusplus.c).
    #[test]
    fn reference_vectors() {
        let mut sm = SplitMix64::new(1234567);
        let expect = [
            6457827717110365317u64,
            3203168211198807973,
            9817491932198370423,
            4593380528125082431,
            16408922859458223821,
        ];
        for e in expect {
            assert_eq!(sm.next_u64(), e);
        }
        // xoshiro256++ from state [1, 2, 3, 4].
        let mut x = Xoshiro256pp { s: [1, 2, 3, 4] };
        let expect = [
            41943041u64,
            58720359,
            3588806011781223,
            3591011842654386,
            9228616714210784205,
        ];
        for e in expect {
            assert_eq!(x.next_u64(), e);
        }
    }

    #[test]
    fn threshold_edges() {
        assert_eq!(bernoulli_threshold(0.0), 0);
        assert_eq!(bernoulli_threshold(-1.0), 0);
        assert_eq!(bernoulli_threshold(f64::NAN), 0);
        assert_eq!(bernoulli_threshold(1.0), u64::MAX);
        assert_eq!(bernoulli_threshold(0.5), 1 << 63);
        assert_eq!(bernoulli_threshold(0.25), 1 << 62);
        let t = bernoulli_threshold(1.0 - f64::EPSILON / 2.0);
        assert_eq!(t, u64::MAX - (1 << 11) + 1);
    }

    /// Simpson's rule for P(|Z| < c), accurate to ~1e-15 here.
    fn prob_abs_below(c: f64) -> f64 {
        let n = 20_000;
        let h = c / n as f64;
        let f = |x: f64| (-0.5 * x * x).exp();
        let mut s = f(0.0) + f(c);
        for i in 1..n {
            s += if i % 2 == 1 { 4.0 } else { 2.0 } * f(i as f64 * h);
        }
        2.0 * s * h / 3.0 / (2.0 * std::f64::consts::PI).sqrt()
    }

    #[test]
    fn ziggurat_is_standard_normal() {
        let z = ziggurat();
        // The top layer must close the table: x_127 (1 - f(x_127)) = V.
        let x127 = z.x[ZIG_LAYERS - 1];
        let top = x127 * (1.0 - (-0.5 * x127 * x127).exp());
        assert!((top - ZIG_V).abs() < 1e-9, "{top}");

        let mut rng = Xoshiro256pp::seed_from_u64(42);
        let n = 2_000_000usize;
        let cuts = [0.25, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, ZIG_R, 4.0];
        let mut counts = vec![0usize; cuts.len()];
        let (mut m1, mut m2, mut m4) = (0.0, 0.0, 0.0);
        let mut positive = 0usize;
        for _ in 0..n {
            let x = rng.normal();
            m1 += x;
            m2 += x * x;
            m4 += x * x * x * x;
            positive += usize::from(x > 0.0);
            for (c, k) in cuts.iter().zip(counts.iter_mut()) {
                *k += usize::from(x.abs() < *c);
            }
        }
        let nf = n as f64;
        assert!((m1 / nf).abs() < 5.0 / nf.sqrt());
        assert!((m2 / nf - 1.0).abs() < 5.0 * 2f64.sqrt() / nf.sqrt());
        assert!((m4 / nf - 3.0).abs() < 5.0 * 96f64.sqrt() / nf.sqrt());
        assert!((positive as f64 / nf - 0.5).abs() < 5.0 * 0.5 / nf.sqrt());
        for (c, k) in cuts.iter().zip(&counts) {
            let p = prob_abs_below(*c);
            let phat = *k as f64 / nf;
            let sd = (p * (1.0 - p) / nf).sqrt();
            assert!((phat - p).abs() < 5.0 * sd, "P(|Z| < {c}): {phat} vs {p}");
        }
    }

    #[test]
    fn streams_differ() {
        let a = SplitMix64::stream(7, 0).next_u64();
        let b = SplitMix64::stream(7, 1).next_u64();
        let c = SplitMix64::stream(8, 0).next_u64();
        assert!(a != b && a != c && b != c);
    }
}
