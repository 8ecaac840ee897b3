//! Perlin noise and the functions built on it: fBm, turbulence and marble.
//! They are the *switches* of section 4.3.1: a marble function chooses
//! between the dark and bright tile maps of the lepidolite (figure 4.7), three
//! Perlin functions shape the patterned sunstone.
//!
//! # Which Perlin
//!
//! The values are those of `noise::Perlin` (noise 0.9): improved Perlin noise
//! with a quintic fade, 12 edge gradients, output scaled by 2/√3 and clamped
//! to `[-1, 1]`, period 256 lattice units, plain `f64` arithmetic
//! (deterministic across platforms; pinned by a golden test). The evaluation
//! is our own re-implementation of `noise::core::perlin::perlin_3d`, operation
//! for operation, over the crate's own permutation table (read once per seed
//! through its public `NoiseHasher`). Tests check it bit for bit against
//! `noise::Perlin`. Why not call the crate directly: its lattice lookup goes
//! through a slice `reduce` and `NumCast(..).unwrap()`, which is several
//! times slower here and panics for non-finite or huge coordinates (beyond
//! `isize`); ours saturates instead and never panics.
//!
//! A [`PerlinSource`] is plain data (a seed and a `[u8; 256]` table), `Copy`,
//! `Send + Sync`: build it once and share it by reference between rayon
//! threads. Building the table shuffles 256 bytes with a seeded RNG, far too
//! slow to repeat per call, which is why the seed is fixed at construction
//! ([`PerlinSource::new`]) instead of being a public field.
//!
//! Every other parameter is a named public field. All functions are pure in
//! `(parameters, object-space point)`.

use glam::DVec3;
use noise::permutationtable::{NoiseHasher, PermutationTable};

/// A seeded Perlin noise lattice (frequency 1: one lattice cell per
/// object-space unit). Value in `[-1, 1]`, 0 on integer lattice points.
#[derive(Clone, Copy, Debug)]
pub struct PerlinSource {
    seed: u64,
    permutation: [u8; 256],
}

/// Folds a 64-bit recipe seed to the `u32` seed of `noise::Perlin`
/// (`low ^ high` 32 bits), so seeds differing only in their high bits still
/// give different patterns; seeds below 2³² are passed through unchanged.
pub const fn perlin_seed_u32(seed: u64) -> u32 {
    (seed ^ (seed >> 32)) as u32
}

/// `trunc` without a library call (the baseline x86-64 target has no SSE4.1
/// `roundsd`, so `f64::trunc` is a software routine). Below 2⁵² in magnitude
/// the integer conversion truncates exactly (only the sign of a zero result
/// differs, which the caller's `− 1` or `x − corner` erases); at and above,
/// every `f64` is already an integer (NaN passes through).
#[inline(always)]
fn trunc_fast(x: f64) -> f64 {
    const ALL_INTEGERS_FROM: f64 = 4_503_599_627_370_496.0; // 2⁵²
    if x.abs() < ALL_INTEGERS_FROM {
        (x as i64) as f64
    } else {
        x
    }
}

/// Lattice corner below `x` exactly as noise 0.9 computes it
/// (`trunc(x) − 1` for `x ≤ 0`, so 0 maps to −1 with fraction 1; the noise
/// is continuous, this only matters for bit-exact agreement), and the low
/// 8 bits of its integer value (saturating cast: no panic on huge input).
#[inline(always)]
fn corner_and_index(x: f64) -> (f64, usize) {
    const ALL_INTEGERS_FROM: f64 = 4_503_599_627_370_496.0; // 2⁵²
    if x.abs() < ALL_INTEGERS_FROM {
        // Branch-free (the sign of x is random; a branch on it mispredicts
        // half the time): corner = trunc(x) − [x ≤ 0] as an integer, exact
        // below 2⁵², and the same f64 as the definition below (a zero corner
        // only arises for x > 0, as +0).
        let corner = x as i64 - i64::from(x <= 0.0);
        (corner as f64, (corner & 0xff) as usize)
    } else {
        corner_and_index_huge(x)
    }
}

/// [`corner_and_index`] for `|x| ≥ 2⁵²` and NaN: the definition as written.
#[cold]
#[inline(never)]
fn corner_and_index_huge(x: f64) -> (f64, usize) {
    let corner = if x <= 0.0 {
        trunc_fast(x) - 1.0
    } else {
        trunc_fast(x)
    };
    (corner, (corner as i64 & 0xff) as usize)
}

/// Gradient dot product of noise 0.9's `perlin_3d`: the low four bits of the
/// corner hash pick one of the 12 cube-edge directions (4 repeated), i.e.
/// `±c[first] ± c[second]` of `c = (x, y, z)`:
///
/// | hash | 0,12 | 1,13 | 2 | 3 | 4 | 5 | 6 | 7 | 8 | 9,14 | 10 | 11,15 |
/// |---|---|---|---|---|---|---|---|---|---|---|---|---|
/// | value | x+y | −x+y | x−y | −x−y | x+z | −x+z | x−z | −x−z | y+z | −y+z | y−z | −y−z |
///
/// Looked up from tables rather than matched: a `match` compiles to an
/// indirect jump per corner, mispredicted about every time (random hashes),
/// which tripled the cost. `(±1)·a + (±1)·b` equals the crate's `a + b`,
/// `-a + b`, `a - b`, `-a - b` bit for bit (multiplying by ±1 and
/// subtracting are exact sign flips in IEEE 754).
#[inline(always)]
fn gradient_dot(hash: u8, x: f64, y: f64, z: f64) -> f64 {
    const FIRST: [usize; 16] = [0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 0, 0, 1, 1];
    const SECOND: [usize; 16] = [1, 1, 1, 1, 2, 2, 2, 2, 2, 2, 2, 2, 1, 1, 2, 2];
    const FIRST_SIGN: [f64; 16] = [
        1., -1., 1., -1., 1., -1., 1., -1., 1., -1., 1., -1., 1., -1., -1., -1.,
    ];
    const SECOND_SIGN: [f64; 16] = [
        1., 1., -1., -1., 1., 1., -1., -1., 1., 1., -1., -1., 1., 1., 1., -1.,
    ];
    let c = [x, y, z];
    let h = (hash & 0b1111) as usize;
    FIRST_SIGN[h] * c[FIRST[h]] + SECOND_SIGN[h] * c[SECOND[h]]
}

/// noise 0.9's `linear`: `b·t + a·(1 − t)` (this operation order).
#[inline(always)]
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    b * t + a * (1.0 - t)
}

/// Perlin's quintic fade 6t⁵ − 15t⁴ + 10t³ (noise 0.9's `map_quintic`).
#[inline(always)]
fn quintic(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

impl PerlinSource {
    /// Builds noise 0.9's permutation table for `seed` (folded by [`perlin_seed_u32`]).
    pub fn new(seed: u64) -> Self {
        let table = PermutationTable::new(perlin_seed_u32(seed));
        let mut permutation = [0u8; 256];
        for (i, entry) in permutation.iter_mut().enumerate() {
            // Hashing a single coordinate returns table[coordinate & 0xff].
            *entry = table.hash(&[i as isize]) as u8;
        }
        PerlinSource { seed, permutation }
    }

    /// The seed this source was built with.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Raw Perlin noise at `p` (lattice units), in `[-1, 1]`; bit-identical
    /// to `noise::Perlin::new(perlin_seed_u32(seed)).get([p.x, p.y, p.z])`.
    #[inline]
    pub fn value(&self, p: DVec3) -> f64 {
        // 2/√3: the unscaled range of 3-D Perlin noise is ±√3/2.
        const SCALE_FACTOR: f64 = 1.154_700_538_379_251_5;
        let perm = &self.permutation;
        let (cx, ix) = corner_and_index(p.x);
        let (cy, iy) = corner_and_index(p.y);
        let (cz, iz) = corner_and_index(p.z);
        let (x0, y0, z0) = (p.x - cx, p.y - cy, p.z - cz);
        let (x1, y1, z1) = (x0 - 1.0, y0 - 1.0, z0 - 1.0);
        // noise 0.9 hashes a corner (x, y, z) as P[P[P[x] ^ y] ^ z], all & 0xff.
        let hash = |x: usize, y: usize, z: usize| {
            let xy = perm[x] as usize ^ y;
            perm[perm[xy] as usize ^ z]
        };
        let (ix1, iy1, iz1) = ((ix + 1) & 0xff, (iy + 1) & 0xff, (iz + 1) & 0xff);
        let g000 = gradient_dot(hash(ix, iy, iz), x0, y0, z0);
        let g100 = gradient_dot(hash(ix1, iy, iz), x1, y0, z0);
        let g010 = gradient_dot(hash(ix, iy1, iz), x0, y1, z0);
        let g110 = gradient_dot(hash(ix1, iy1, iz), x1, y1, z0);
        let g001 = gradient_dot(hash(ix, iy, iz1), x0, y0, z1);
        let g101 = gradient_dot(hash(ix1, iy, iz1), x1, y0, z1);
        let g011 = gradient_dot(hash(ix, iy1, iz1), x0, y1, z1);
        let g111 = gradient_dot(hash(ix1, iy1, iz1), x1, y1, z1);
        let (u, v, w) = (quintic(x0), quintic(y0), quintic(z0));
        let result = lerp(
            lerp(lerp(g000, g001, w), lerp(g010, g011, w), v),
            lerp(lerp(g100, g101, w), lerp(g110, g111, w), v),
            u,
        ) * SCALE_FACTOR;
        result.clamp(-1.0, 1.0)
    }
}

impl PartialEq for PerlinSource {
    /// Two sources are equal when built from the same seed (the table is a
    /// function of the seed).
    fn eq(&self, other: &Self) -> bool {
        self.seed == other.seed
    }
}

/// Offset added to octave `k` (times `k`): Perlin noise vanishes on integer
/// lattice points, and with an integer lacunarity every octave's lattice
/// contains the coarser ones, so without a shift all octaves would vanish
/// together there (and at the origin). Irrational-looking, non-lattice values.
const OCTAVE_SHIFT: DVec3 = DVec3::new(0.537_7, 0.273_1, 0.811_9);

/// `Σ_{k < octaves} gainᵏ · shape(noise(p · frequency · lacunarityᵏ + k · OCTAVE_SHIFT))`.
#[inline(always)]
fn octave_sum(
    source: &PerlinSource,
    p: DVec3,
    frequency: f64,
    octaves: u32,
    lacunarity: f64,
    gain: f64,
    shape: impl Fn(f64) -> f64,
) -> f64 {
    let never_stop = |_: u32, _: f64, _: f64| None::<std::convert::Infallible>;
    match octave_sum_until(
        source, p, frequency, octaves, lacunarity, gain, shape, never_stop,
    ) {
        Ok(never) => match never {},
        Err(sum) => sum,
    }
}

/// [`octave_sum`], calling `after_octave(k, sum so far, gainᵏ)` after
/// octave k is added; `Ok(r)` as soon as it returns `Some(r)`, otherwise
/// `Err(sum)` with the whole sum (the same operations in the same order, so
/// the same bits, as without the calls).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn octave_sum_until<R>(
    source: &PerlinSource,
    p: DVec3,
    frequency: f64,
    octaves: u32,
    lacunarity: f64,
    gain: f64,
    shape: impl Fn(f64) -> f64,
    mut after_octave: impl FnMut(u32, f64, f64) -> Option<R>,
) -> Result<R, f64> {
    let mut sum = 0.0;
    let mut octave_frequency = frequency;
    let mut amplitude = 1.0;
    let mut shift = DVec3::ZERO;
    for k in 0..octaves {
        let octave_amplitude = amplitude;
        sum += octave_amplitude * shape(source.value(p * octave_frequency + shift));
        octave_frequency *= lacunarity;
        amplitude *= gain;
        shift += OCTAVE_SHIFT;
        if let Some(r) = after_octave(k, sum, octave_amplitude) {
            return Ok(r);
        }
    }
    Err(sum)
}

/// `Σ_{k < octaves} |gain|ᵏ`: the largest magnitude an octave sum can reach.
fn amplitude_bound(octaves: u32, gain: f64) -> f64 {
    let mut sum = 0.0;
    let mut amplitude = 1.0;
    for _ in 0..octaves {
        sum += amplitude;
        amplitude *= gain.abs();
    }
    sum
}

/// Perlin noise at a chosen frequency: `noise(p · frequency)`, in `[-1, 1]`.
/// One of the sunstone's switches (section 4.3.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerlinNoise {
    /// The seeded noise lattice.
    pub source: PerlinSource,
    /// Lattice cells per object-space unit (feature size ≈ 1 / frequency).
    pub frequency: f64,
}

impl PerlinNoise {
    /// Noise value at object-space `p`, in `[-1, 1]`.
    #[inline]
    pub fn value(&self, p: DVec3) -> f64 {
        self.source.value(p * self.frequency)
    }
}

/// Fractional Brownian motion: a sum of Perlin octaves,
/// `Σ_{k < octaves} gainᵏ · noise(p · frequency · lacunarityᵏ)` (each octave
/// also shifted, see the source). Not normalised: `|value| ≤ amplitude_bound()`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fbm {
    /// The seeded noise lattice shared by all octaves.
    pub source: PerlinSource,
    /// Frequency of the first octave, lattice cells per object-space unit.
    pub frequency: f64,
    /// Number of octaves summed.
    pub octaves: u32,
    /// Frequency ratio between successive octaves (typically 2).
    pub lacunarity: f64,
    /// Amplitude ratio between successive octaves (typically 0.5).
    pub gain: f64,
}

impl Fbm {
    /// fBm value at object-space `p`, in `[-amplitude_bound(), amplitude_bound()]`.
    #[inline]
    pub fn value(&self, p: DVec3) -> f64 {
        octave_sum(
            &self.source,
            p,
            self.frequency,
            self.octaves,
            self.lacunarity,
            self.gain,
            |n| n,
        )
    }

    /// `Σ |gain|ᵏ` over the octaves: a bound on `|value|`.
    pub fn amplitude_bound(&self) -> f64 {
        amplitude_bound(self.octaves, self.gain)
    }
}

/// Perlin's turbulence: `Σ_{k < octaves} gainᵏ · |noise(p · frequency · lacunarityᵏ)|`,
/// our own sum of absolute octaves (not `noise::Turbulence`, which warps
/// coordinates instead). The creases where octaves change sign give the veins
/// of marble. In `[0, amplitude_bound()]` for `gain ≥ 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Turbulence {
    /// The seeded noise lattice shared by all octaves.
    pub source: PerlinSource,
    /// Frequency of the first octave, lattice cells per object-space unit.
    pub frequency: f64,
    /// Number of octaves summed.
    pub octaves: u32,
    /// Frequency ratio between successive octaves (typically 2).
    pub lacunarity: f64,
    /// Amplitude ratio between successive octaves (typically 0.5; keep ≥ 0
    /// for a non-negative sum).
    pub gain: f64,
}

impl Turbulence {
    /// Turbulence at object-space `p`.
    #[inline]
    pub fn value(&self, p: DVec3) -> f64 {
        octave_sum(
            &self.source,
            p,
            self.frequency,
            self.octaves,
            self.lacunarity,
            self.gain,
            f64::abs,
        )
    }

    /// `Σ |gain|ᵏ` over the octaves: a bound on the value.
    pub fn amplitude_bound(&self) -> f64 {
        amplitude_bound(self.octaves, self.gain)
    }
}

/// Perlin's marble: stripes along `direction` disturbed by turbulence,
/// `0.5 + 0.5 · sin(frequency · (p · direction) + amplitude · turbulence(p))`,
/// in `[0, 1]`. The lepidolite switches dark/bright tiles with it (figure 4.7).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Marble {
    /// Axis across which the stripes alternate (need not be unit length; its
    /// length multiplies `frequency`).
    pub direction: DVec3,
    /// Stripe phase rate, radians per object-space unit along a unit
    /// `direction` (stripe period 2π / frequency).
    pub frequency: f64,
    /// How strongly turbulence bends the stripes, radians per unit of turbulence.
    pub amplitude: f64,
    /// The turbulence that bends the stripes.
    pub turbulence: Turbulence,
}

impl Marble {
    /// Marble value at object-space `p`, in `[0, 1]`.
    #[inline]
    pub fn value(&self, p: DVec3) -> f64 {
        let phase =
            self.frequency * p.dot(self.direction) + self.amplitude * self.turbulence.value(p);
        0.5 + 0.5 * phase.sin()
    }

    /// [`Marble::value`], unless `settle` decides first: after each octave
    /// but the last, `settle(lo, hi)` gets an interval of phases (radians)
    /// sure to hold the final phase `frequency · p·direction + amplitude ·
    /// turbulence(p)` (the octaves still to come add at most `|gain|ᵏ` each,
    /// Perlin noise being clamped to `[-1, 1]`); when it returns `Some(r)`
    /// the remaining octaves are skipped and `Ok(r)` returned. Otherwise
    /// `Err(value)` with the value bit for bit equal to [`Marble::value`]
    /// (same operations in the same order). A switch only needs to know
    /// which range the value falls in, which is often settled after two or
    /// three of the four octaves.
    #[inline]
    pub fn value_unless<R>(
        &self,
        p: DVec3,
        mut settle: impl FnMut(f64, f64) -> Option<R>,
    ) -> Result<R, f64> {
        let t = &self.turbulence;
        let linear = self.frequency * p.dot(self.direction);
        // Σ_{k ≥ K} |gain|ᵏ for the octaves not yet summed, updated by
        // subtraction (its rounding is far below the caller's margin).
        let mut rest_bound = amplitude_bound(t.octaves, t.gain);
        // The turbulence's own octave sum (shape = abs): the same bits.
        let turbulence = octave_sum_until(
            &t.source,
            p,
            t.frequency,
            t.octaves,
            t.lacunarity,
            t.gain,
            f64::abs,
            |k, sum, octave_amplitude| {
                rest_bound -= octave_amplitude.abs();
                if k + 1 == t.octaves {
                    return None;
                }
                // Turbulence ∈ [sum − rest·[gain < 0], sum + rest].
                let low = if t.gain < 0.0 { sum - rest_bound } else { sum };
                let high = sum + rest_bound;
                let (a, b) = (self.amplitude * low, self.amplitude * high);
                settle(linear + a.min(b), linear + a.max(b))
            },
        );
        turbulence.map_err(|sum| 0.5 + 0.5 * (linear + self.amplitude * sum).sin())
    }
}
