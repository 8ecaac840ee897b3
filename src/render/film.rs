//! The film: every pixel's samples, filtered, averaged, with its AOVs.
//!
//! Pixels are independent: pixel (x, y) draws its samples from
//! `SampleStream`s keyed by (seed, pixel, sample), so rows can be
//! rendered by any thread in any order and the result is the same bytes.
//! The reconstruction filter ([`PixelFilter`]: a tent of radius one pixel
//! by default, the pixel's own box, or a Gaussian) is applied by filter importance
//! sampling (each sample's film position is drawn from the filter, all
//! weights are 1), which keeps pixels independent.

use glam::DVec3;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::brdf::Rgb;
use crate::render::camera::PinholeCamera;
use crate::render::cpu::CodePath;
use crate::render::integrator::{FirstHitSums, RayCounts};
use crate::render::render_scene::RenderScene;
use crate::render::sampler::{PixelSampler, SampleBatch, SAMPLE_BATCH};
use crate::sampling::sin_cos_turns;

/// What to render.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FilmSettings {
    /// Image width in pixels, ≥ 1.
    pub width: u32,
    /// Image height in pixels, ≥ 1.
    pub height: u32,
    /// Samples per pixel, ≥ 1.
    pub samples_per_pixel: u32,
    /// Seed of every random number of the render.
    pub seed: u64,
    /// The most CPU-specific copy of the pixel loop to run (capped at
    /// [`CodePath::best_available`]); every copy writes the same bytes.
    pub code_path: CodePath,
    /// The reconstruction filter.
    pub filter: PixelFilter,
}

/// The reconstruction filter: the weight a pixel gives a sample by where
/// it crosses the film, as a density the sample's position is drawn from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PixelFilter {
    /// A tent of radius one pixel about the pixel's centre (separable, 1 −
    /// |t| along each axis): neighbouring pixels share samples' regions, so
    /// edges are smoother, and a point brighter than its surroundings (a
    /// glint) shows in its neighbours too.
    #[default]
    Tent,
    /// The pixel's own square: every sample inside the pixel, none shared;
    /// crisper, and a glint stays in its pixel (Mitsuba's `box` film).
    Box,
    /// A round Gaussian of standard deviation ½ pixel about the pixel's
    /// centre, cut off at 1.5 pixels (3σ; pbrt-v4's default widths): the
    /// softest of the three.
    Gaussian,
}

/// The Gaussian filter's standard deviation, pixels.
const GAUSSIAN_SIGMA_PX: f64 = 0.5;
/// The Gaussian filter's radius, pixels.
const GAUSSIAN_RADIUS_PX: f64 = 1.5;

impl FilmSettings {
    /// `width` × `height` pixels, `samples_per_pixel` samples each, drawn
    /// from `seed`, on the best copy of the pixel loop this CPU runs.
    ///
    /// # Panics
    ///
    /// If a size or the sample count is 0 (a film of no pixels, or of
    /// pixels without a sample).
    pub fn new(width: u32, height: u32, samples_per_pixel: u32, seed: u64) -> Self {
        assert!(
            width > 0 && height > 0 && samples_per_pixel > 0,
            "a film needs at least one pixel and one sample per pixel: {width} × {height}, {samples_per_pixel} spp"
        );
        Self {
            width,
            height,
            samples_per_pixel,
            seed,
            code_path: CodePath::best_available(),
            filter: PixelFilter::Tent,
        }
    }
}

/// Bytes of film memory per pixel (RGBA, albedo, normal, depth, cell,
/// glitter, inclusion, material id, ambient occlusion as f32/u32, plus the
/// 8-bit image); the output encoders need about as much again at the end.
pub const FILM_BYTES_PER_PIXEL: u64 = 4 * (4 + 3 + 3 + 1 + 1 + 1 + 1 + 1 + 1) + 3;

/// The rendered film: linear radiance and the AOVs, row-major from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB radiance, mean of the samples.
    pub rgb: Vec<[f32; 3]>,
    /// Fraction of samples that hit a surface (stone or ground).
    pub alpha: Vec<f32>,
    /// Mean first-hit directional albedo.
    pub albedo: Vec<[f32; 3]>,
    /// Mean first-hit world shading normal (not renormalised: its length
    /// shows how much the normals in the pixel agree).
    pub normal: Vec<[f32; 3]>,
    /// Mean distance from the camera over the samples that hit; infinite
    /// where none did.
    pub depth: Vec<f32>,
    /// Surface-map cell id of the pixel's first sample (0 off the stones).
    pub surface_cell: Vec<u32>,
    /// Fraction of samples that hit a glitter flake.
    pub glitter: Vec<f32>,
    /// Fraction of samples whose camera ray refracted into a translucent
    /// stone and met an inclusion (a flake) before scattering or reaching
    /// the surface again; 0 off such stones.
    pub inclusion: Vec<f32>,
    /// Material id of the pixel's first sample (0 background, 1 ground,
    /// 2… the stones' materials).
    pub material_id: Vec<u32>,
    /// Mean unoccluded fraction (ambient occlusion; all 1 when it is off).
    pub ao: Vec<f32>,
    /// Statistics of the render.
    pub stats: RenderStats,
}

/// Counts gathered while rendering.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Camera and path rays traced.
    pub traced_rays: u64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// Samples whose radiance was NaN, infinite or negative, dropped from
    /// the film (counted so a user can see the integrator misbehaved).
    pub bad_samples: u64,
}

impl RenderStats {
    /// The counts of two parts of a film together.
    fn plus(self, other: Self) -> Self {
        RenderStats {
            traced_rays: self.traced_rays + other.traced_rays,
            shadow_rays: self.shadow_rays + other.shadow_rays,
            bad_samples: self.bad_samples + other.bad_samples,
        }
    }
}

/// Pixels in the unit of parallel work: a row is cut into spans of this
/// many, so that at the end of a film the last rows are shared among the
/// cores instead of each waiting on one thread (a row of the peer scene
/// at 64 spp is ≈ 10 ms on one core; a span of 64 pixels ≈ 1 ms). Each
/// pixel is keyed by its place in the film: the same bytes at any span.
const SPAN_PIXELS: usize = 64;

/// A span of pixels of one row of the film, borrowed for writing.
struct SpanOut<'a> {
    rgb: &'a mut [[f32; 3]],
    alpha: &'a mut [f32],
    albedo: &'a mut [[f32; 3]],
    normal: &'a mut [[f32; 3]],
    depth: &'a mut [f32],
    surface_cell: &'a mut [u32],
    glitter: &'a mut [f32],
    inclusion: &'a mut [f32],
    material_id: &'a mut [u32],
    ao: &'a mut [f32],
}

impl<'a> SpanOut<'a> {
    /// The span cut into consecutive spans of `pixels` (the last one
    /// shorter), in parallel: the film into rows, a row into spans.
    fn into_chunks(self, pixels: usize) -> impl IndexedParallelIterator<Item = SpanOut<'a>> {
        (
            self.rgb.par_chunks_mut(pixels),
            self.alpha.par_chunks_mut(pixels),
            self.albedo.par_chunks_mut(pixels),
            self.normal.par_chunks_mut(pixels),
            self.depth.par_chunks_mut(pixels),
            self.surface_cell.par_chunks_mut(pixels),
            self.glitter.par_chunks_mut(pixels),
            self.inclusion.par_chunks_mut(pixels),
            self.material_id.par_chunks_mut(pixels),
            self.ao.par_chunks_mut(pixels),
        )
            .into_par_iter()
            .map(
                |(
                    rgb,
                    alpha,
                    albedo,
                    normal,
                    depth,
                    surface_cell,
                    glitter,
                    inclusion,
                    material_id,
                    ao,
                )| SpanOut {
                    rgb,
                    alpha,
                    albedo,
                    normal,
                    depth,
                    surface_cell,
                    glitter,
                    inclusion,
                    material_id,
                    ao,
                },
            )
    }
}

/// A sample of the tent filter of radius 1 by inverting its CDF.
///
/// Both halves share one square root, √(2·min(u, 1−u)) − 1, negated for
/// u ≥ ½ (2 − 2u = 2(1 − u) exactly, Sterbenz): the same bits as the two
/// branches, without a 50/50 branch the processor cannot predict.
#[inline(always)]
fn tent(u: f64) -> f64 {
    let half = (2.0 * u.min(1.0 - u)).sqrt() - 1.0;
    let sign_bit = if u < 0.5 { 0 } else { 1u64 << 63 };
    f64::from_bits(half.to_bits() ^ sign_bit)
}

/// The camera rays' directions for the first `lanes` samples of a batch of
/// pixel (x, y): the footprints (pair 0) through the pixel filter, then
/// [`PinholeCamera::directions`]; the same bits as `camera.ray` per sample.
/// Inlined into the pixel loop, whose x86-64-v3 copy compiles the lanes four
/// to a register. A partial batch (a pixel's last samples)
/// takes one `camera.ray` per sample instead.
#[inline(always)]
fn camera_directions(
    camera: &PinholeCamera,
    x: u32,
    y: u32,
    batch: &SampleBatch,
    lanes: u32,
    filter: PixelFilter,
) -> [DVec3; SAMPLE_BATCH as usize] {
    if lanes < SAMPLE_BATCH {
        let mut directions = [DVec3::ZERO; SAMPLE_BATCH as usize];
        let footprints = batch.footprints();
        for (footprint, direction) in footprints.iter().zip(&mut directions).take(lanes as usize) {
            let (film_x, film_y) = film_point(x, y, *footprint, filter);
            *direction = camera.ray(film_x, film_y).direction;
        }
        return directions;
    }
    camera_directions_lanes(camera, x, y, batch, filter)
}

/// See [`camera_directions`].
#[inline(always)]
fn camera_directions_lanes(
    camera: &PinholeCamera,
    x: u32,
    y: u32,
    batch: &SampleBatch,
    filter: PixelFilter,
) -> [DVec3; SAMPLE_BATCH as usize] {
    let (x_px, y_px) = film_points(x, y, batch, filter);
    camera.directions(&x_px, &y_px)
}

/// Where each lane's camera ray crosses the film of pixel (x, y). One
/// branch on the filter for the whole batch, so each arm's lane loop
/// stays branch-free.
#[inline(always)]
fn film_points(
    x: u32,
    y: u32,
    batch: &SampleBatch,
    filter: PixelFilter,
) -> ([f64; SAMPLE_BATCH as usize], [f64; SAMPLE_BATCH as usize]) {
    let footprints = batch.footprints();
    // The separable filters axis by axis (as [`film_point`]), so that each
    // axis's lanes stay one straight loop.
    let (centre_x, centre_y) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
    match filter {
        PixelFilter::Tent => (
            footprints.map(|[fx, _]| centre_x + tent(fx)),
            footprints.map(|[_, fy]| centre_y + tent(fy)),
        ),
        PixelFilter::Box => (
            footprints.map(|[fx, _]| f64::from(x) + fx),
            footprints.map(|[_, fy]| f64::from(y) + fy),
        ),
        PixelFilter::Gaussian => {
            let points = footprints.map(|footprint| film_point(x, y, footprint, filter));
            (points.map(|(px, _)| px), points.map(|(_, py)| py))
        }
    }
}

/// Where a sample of pixel (x, y) crosses the film: the pixel's centre
/// moved by `footprint` (uniform in [0, 1)²) through the filter's inverse
/// CDF. The tent and the box are separable, one coordinate each (the box:
/// the pixel's lower corner plus `footprint`); the Gaussian is round: the
/// first number draws the radius from its truncated Rayleigh distribution
/// (CDF (1 − e^(−r²/2σ²)) / (1 − e^(−R²/2σ²)) for r ≤ R), the second the
/// angle.
#[inline(always)]
fn film_point(x: u32, y: u32, [fx, fy]: [f64; 2], filter: PixelFilter) -> (f64, f64) {
    let (centre_x, centre_y) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
    match filter {
        PixelFilter::Tent => (centre_x + tent(fx), centre_y + tent(fy)),
        PixelFilter::Box => (f64::from(x) + fx, f64::from(y) + fy),
        PixelFilter::Gaussian => {
            let two_variance = 2.0 * GAUSSIAN_SIGMA_PX * GAUSSIAN_SIGMA_PX;
            // 1 − e^(−R²/2σ²), the share of the whole Gaussian inside R.
            let inside = -(-GAUSSIAN_RADIUS_PX * GAUSSIAN_RADIUS_PX / two_variance).exp_m1();
            let radius = (-two_variance * (-fx * inside).ln_1p()).sqrt();
            let (sin, cos) = sin_cos_turns(fy);
            (centre_x + radius * cos, centre_y + radius * sin)
        }
    }
}

fn to_f32x3(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// Renders the pixels of row `y` from column `x_first` on into `span`
/// (one span of the row); returns their ray counts.
///
/// The one place where a per-CPU copy is chosen
/// ([`crate::render::cpu`]): with [`CodePath::X86_64V3`] the span is
/// rendered by a copy of the same code compiled for those features (VEX
/// three-operand instructions drop register copies and spills from the
/// path tracer's loop; the sampler's and camera's lane loops inline into
/// it and run on AVX2). Both copies write the same bytes (tested).
fn render_span(
    scene: &RenderScene,
    camera: &PinholeCamera,
    settings: &FilmSettings,
    y: u32,
    x_first: u32,
    span: SpanOut<'_>,
) -> RenderStats {
    #[cfg(target_arch = "x86_64")]
    if settings.code_path.min(CodePath::best_available()) == CodePath::X86_64V3 {
        // SAFETY: this CPU has every feature of the copy.
        return unsafe { render_span_x86_64_v3(scene, camera, settings, y, x_first, span) };
    }
    render_span_portable(scene, camera, settings, y, x_first, span)
}

/// [`render_span_portable`] compiled for x86-64-v3 (see [`render_span`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt")]
fn render_span_x86_64_v3(
    scene: &RenderScene,
    camera: &PinholeCamera,
    settings: &FilmSettings,
    y: u32,
    x_first: u32,
    span: SpanOut<'_>,
) -> RenderStats {
    render_span_portable(scene, camera, settings, y, x_first, span)
}

/// The pixel loop itself, for the baseline x86-64 (or any other) target;
/// inlined into [`render_span_x86_64_v3`] for the other copy. Each sample
/// is traced by [`RenderScene::radiance`] and summed in sample order.
#[inline(always)]
fn render_span_portable(
    scene: &RenderScene,
    camera: &PinholeCamera,
    settings: &FilmSettings,
    y: u32,
    x_first: u32,
    span: SpanOut<'_>,
) -> RenderStats {
    let mut stats = RenderStats::default();
    let spp = settings.samples_per_pixel;
    // The pairs every sample draws, made for
    // the batch at once; deeper ones when a path draws them.
    let eager_pairs = scene.first_vertex_pairs();
    for (i, x) in (x_first..).take(span.rgb.len()).enumerate() {
        let pixel_index = u64::from(y) * u64::from(settings.width) + u64::from(x);
        let pixel = PixelSampler::new(settings.seed, pixel_index);
        let mut sum = Rgb::ZERO;
        let mut first_hits = FirstHitSums::default();
        // The Sobol points of SAMPLE_BATCH samples at a time, made together.
        let mut batch = SampleBatch::default();
        for first_sample in (0..spp).step_by(SAMPLE_BATCH as usize) {
            let lanes = (spp - first_sample).min(SAMPLE_BATCH);
            pixel.refill(&mut batch, first_sample, lanes, eager_pairs);
            let directions = camera_directions(camera, x, y, &batch, lanes, settings.filter);
            for lane in 0..lanes {
                let s = first_sample + lane;
                let mut stream = batch.stream(lane);
                stream.skip_2d(); // the footprint, already in `directions`
                let mut counts = RayCounts::default();
                let radiance = scene.radiance(
                    (
                        camera.position(),
                        directions[lane as usize],
                        camera.pixel_angle_rad(),
                    ),
                    &mut stream,
                    &mut counts,
                    &mut first_hits,
                    s == 0,
                );
                stats.traced_rays += counts.traced;
                stats.shadow_rays += counts.shadow;
                if radiance.is_finite() && radiance.min_element() >= 0.0 {
                    sum += radiance;
                } else {
                    stats.bad_samples += 1;
                }
            }
        }
        let n = f64::from(spp);
        span.rgb[i] = to_f32x3(sum / n);
        let first = &first_hits;
        span.alpha[i] = (f64::from(first.hits) / n) as f32;
        span.albedo[i] = to_f32x3(first.albedo / n);
        span.normal[i] = to_f32x3(first.normal / n);
        span.depth[i] = if first.hits > 0 {
            (first.depth / f64::from(first.hits)) as f32
        } else {
            f32::INFINITY
        };
        span.surface_cell[i] = first.surface_cell;
        span.glitter[i] = (f64::from(first.glints) / n) as f32;
        span.inclusion[i] = (f64::from(first.inclusions) / n) as f32;
        span.material_id[i] = first.material_id;
        span.ao[i] = (first.unoccluded / n) as f32;
    }
    stats
}

/// Renders the film on the current rayon pool. `progress` is called with
/// each finished span's number of pixels (from any thread, in any order).
pub fn render(
    scene: &RenderScene,
    camera: &PinholeCamera,
    settings: &FilmSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Film {
    let never = AtomicBool::new(false);
    render_cancellable(scene, camera, settings, progress, &never)
        .expect("a render that cannot be cancelled finishes")
}

/// [`render`], stopping early (returning None) once `cancel` is set, e.g.
/// by Ctrl-C. Spans of rows already started finish, the others are skipped; no
/// partial film is returned.
pub fn render_cancellable(
    scene: &RenderScene,
    camera: &PinholeCamera,
    settings: &FilmSettings,
    progress: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> Option<Film> {
    render_rows_cancellable(
        scene,
        camera,
        settings,
        0..settings.height,
        progress,
        cancel,
    )
}

/// [`render_cancellable`] for the rows `rows` of the film alone (a tile,
/// [`crate::render::tiles`]): a [`Film`] `rows.len()` pixels high whose
/// rows are the same bits as those rows of the whole film, because every
/// pixel is keyed by its place in the whole film. `rows` must lie within
/// `0..settings.height`.
pub fn render_rows_cancellable(
    scene: &RenderScene,
    camera: &PinholeCamera,
    settings: &FilmSettings,
    rows: Range<u32>,
    progress: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> Option<Film> {
    assert!(
        rows.start <= rows.end && rows.end <= settings.height,
        "rows {rows:?} outside a film {} high",
        settings.height
    );
    let first_row = rows.start;
    let height = rows.end - rows.start;
    let pixels = settings.width as usize * height as usize;
    let w = settings.width as usize;
    let mut film = Film {
        width: settings.width,
        height,
        rgb: vec![[0.0; 3]; pixels],
        alpha: vec![0.0; pixels],
        albedo: vec![[0.0; 3]; pixels],
        normal: vec![[0.0; 3]; pixels],
        depth: vec![0.0; pixels],
        surface_cell: vec![0; pixels],
        glitter: vec![0.0; pixels],
        inclusion: vec![0.0; pixels],
        material_id: vec![0; pixels],
        ao: vec![0.0; pixels],
        stats: RenderStats::default(),
    };
    // Every span of a row is written in place by whichever thread takes
    // it: no barrier between groups of rows (an idle core steals the next
    // row, or the rest of a row, at once) and no second copy of the film.
    let whole = SpanOut {
        rgb: &mut film.rgb,
        alpha: &mut film.alpha,
        albedo: &mut film.albedo,
        normal: &mut film.normal,
        depth: &mut film.depth,
        surface_cell: &mut film.surface_cell,
        glitter: &mut film.glitter,
        inclusion: &mut film.inclusion,
        material_id: &mut film.material_id,
        ao: &mut film.ao,
    };
    let stats = whole
        .into_chunks(w)
        .enumerate()
        .map(|(y, row)| {
            row.into_chunks(SPAN_PIXELS)
                .enumerate()
                .map(|(k, span)| {
                    if cancel.load(Ordering::Relaxed) {
                        return RenderStats::default();
                    }
                    let pixels = span.rgb.len() as u64;
                    let x_first = (k * SPAN_PIXELS) as u32;
                    let stats =
                        render_span(scene, camera, settings, first_row + y as u32, x_first, span);
                    progress(pixels);
                    stats
                })
                .reduce(RenderStats::default, RenderStats::plus)
        })
        .reduce(RenderStats::default, RenderStats::plus);
    if cancel.load(Ordering::Relaxed) {
        return None;
    }
    film.stats = stats;
    Some(film)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recipe::gem::GemSource;
    use crate::recipe::TableCache;
    use crate::recipe::Tables;
    use crate::render::prepare;
    use crate::render::render_scene::MATERIAL_ID_FIRST_STONE;
    use crate::scene::default_scene;

    #[test]
    fn every_span_renders_its_own_pixels_as_one_pixel_alone_would() {
        // Rows 130 pixels wide (spans of 64, 64 and 2) against each
        // pixel rendered as a span of its own: every AOV the same bits,
        // so a span's pixels are keyed by their place in the row.
        let scene = default_scene();
        let gem = GemSource::load("sunstone").unwrap();
        let cache = TableCache::in_memory();
        let traced =
            prepare::prepare_scene(&scene, &gem, None, 1, Tables::Computed(&cache), &|_| {})
                .unwrap();
        // Rows through the middle of a square film (a tile of them).
        let (width, height, rows) = (130, 130, 62..65);
        let camera = prepare::camera_for(&scene, width, height);
        let settings = FilmSettings::new(width, height, 2, 7);
        let never = AtomicBool::new(false);
        let film =
            render_rows_cancellable(&traced, &camera, &settings, rows.clone(), &|_| {}, &never)
                .unwrap();
        let mut covered = 0;
        for y in rows.clone() {
            for x in 0..width {
                let mut pixel = ([[0.0f32; 3]; 3], [0.0f32; 5], [0u32; 2]);
                let ([rgb, albedo, normal], [alpha, depth, glitter, inclusion, ao], [cell, id]) =
                    &mut pixel;
                let span = SpanOut {
                    rgb: std::slice::from_mut(rgb),
                    alpha: std::slice::from_mut(alpha),
                    albedo: std::slice::from_mut(albedo),
                    normal: std::slice::from_mut(normal),
                    depth: std::slice::from_mut(depth),
                    surface_cell: std::slice::from_mut(cell),
                    glitter: std::slice::from_mut(glitter),
                    inclusion: std::slice::from_mut(inclusion),
                    material_id: std::slice::from_mut(id),
                    ao: std::slice::from_mut(ao),
                };
                render_span(&traced, &camera, &settings, y, x, span);
                let i = ((y - rows.start) * width + x) as usize;
                let bits = |v: &[f32]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(rgb), bits(&film.rgb[i]), "rgb at ({x}, {y})");
                assert_eq!(bits(albedo), bits(&film.albedo[i]), "albedo at ({x}, {y})");
                assert_eq!(bits(normal), bits(&film.normal[i]), "normal at ({x}, {y})");
                let scalars = [*alpha, *depth, *glitter, *inclusion, *ao];
                let film_scalars = [
                    film.alpha[i],
                    film.depth[i],
                    film.glitter[i],
                    film.inclusion[i],
                    film.ao[i],
                ];
                assert_eq!(bits(&scalars), bits(&film_scalars), "scalars at ({x}, {y})");
                assert_eq!([*cell, *id], [film.surface_cell[i], film.material_id[i]]);
                covered += usize::from(film.material_id[i] >= MATERIAL_ID_FIRST_STONE);
            }
        }
        // The stone is in these rows, beside the ground and the sky.
        assert!(covered > 10, "{covered} pixels saw the stone");
    }

    /// The tent's inverse CDF written out by halves: F(t) = (1 + t)²/2 on
    /// [−1, 0] and 1 − (1 − t)²/2 on [0, 1].
    fn tent_by_halves(u: f64) -> f64 {
        if u < 0.5 {
            (2.0 * u).sqrt() - 1.0
        } else {
            1.0 - (2.0 - 2.0 * u).sqrt()
        }
    }

    #[test]
    fn the_branch_free_tent_is_the_inverse_cdf_bit_for_bit() {
        let mut u = 0.0f64;
        let mut checked = 0;
        while u < 1.0 {
            assert_eq!(tent(u), tent_by_halves(u), "u = {u}");
            // Irregular steps, plus the edges around ½.
            u += 0.000_123_456_7 * (1.0 + (checked % 7) as f64);
            checked += 1;
        }
        for u in [0.0, 0.5, 0.5 - f64::EPSILON / 4.0, 1.0 - f64::EPSILON / 2.0] {
            assert_eq!(tent(u), tent_by_halves(u), "u = {u}");
        }
        assert!(checked > 1000);
    }
}
