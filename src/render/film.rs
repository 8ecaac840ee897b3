//! The film: every pixel's samples, filtered, averaged, with its AOVs.
//!
//! Pixels are independent: pixel (x, y) draws its samples from
//! [`SampleStream`]s keyed by (seed, pixel, sample), so rows can be
//! rendered by any thread in any order and the result is the same bytes.
//! The reconstruction filter is a tent of radius one pixel, applied by
//! filter importance sampling (each sample's film position is drawn from
//! the filter, all weights are 1), which keeps pixels independent.

use glam::DVec3;
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::brdf::Rgb;
use crate::render::camera::PinholeCamera;
use crate::render::integrator::{RayCounts, RenderScene};
use crate::render::sampler::SampleStream;

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
}

/// Bytes of film memory per pixel (RGBA, albedo, normal, depth, cell,
/// glitter, material id, ambient occlusion as f32/u32, plus the 8-bit
/// image); the output encoders need about as much again at the end.
pub const FILM_BYTES_PER_PIXEL: u64 = 4 * (4 + 3 + 3 + 1 + 1 + 1 + 1 + 1) + 3;

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

/// One row's pixels before assembly.
struct Row {
    rgb: Vec<[f32; 3]>,
    alpha: Vec<f32>,
    albedo: Vec<[f32; 3]>,
    normal: Vec<[f32; 3]>,
    depth: Vec<f32>,
    surface_cell: Vec<u32>,
    glitter: Vec<f32>,
    material_id: Vec<u32>,
    ao: Vec<f32>,
    stats: RenderStats,
}

/// A sample of the tent filter of radius 1 by inverting its CDF.
fn tent(u: f64) -> f64 {
    if u < 0.5 {
        (2.0 * u).sqrt() - 1.0
    } else {
        1.0 - (2.0 - 2.0 * u).sqrt()
    }
}

fn to_f32x3(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

fn render_row(scene: &RenderScene, camera: &PinholeCamera, settings: &FilmSettings, y: u32) -> Row {
    let w = settings.width as usize;
    let mut row = Row {
        rgb: Vec::with_capacity(w),
        alpha: Vec::with_capacity(w),
        albedo: Vec::with_capacity(w),
        normal: Vec::with_capacity(w),
        depth: Vec::with_capacity(w),
        surface_cell: Vec::with_capacity(w),
        glitter: Vec::with_capacity(w),
        material_id: Vec::with_capacity(w),
        ao: Vec::with_capacity(w),
        stats: RenderStats::default(),
    };
    let spp = settings.samples_per_pixel;
    for x in 0..settings.width {
        let pixel_index = u64::from(y) * u64::from(settings.width) + u64::from(x);
        let mut sum = Rgb::ZERO;
        let mut albedo = Rgb::ZERO;
        let mut normal = DVec3::ZERO;
        let (mut depth_sum, mut hits, mut glints) = (0.0, 0u32, 0u32);
        let (mut cell, mut material) = (0, 0);
        let mut unoccluded = 0.0;
        for s in 0..spp {
            let mut stream = SampleStream::new(settings.seed, pixel_index, s);
            let [fx, fy] = stream.next_2d();
            let ray = camera.ray(f64::from(x) + 0.5 + tent(fx), f64::from(y) + 0.5 + tent(fy));
            let mut counts = RayCounts::default();
            let (radiance, first) =
                scene.radiance(ray.origin, ray.direction, &mut stream, &mut counts);
            row.stats.traced_rays += counts.traced;
            row.stats.shadow_rays += counts.shadow;
            if radiance.is_finite() && radiance.min_element() >= 0.0 {
                sum += radiance;
            } else {
                row.stats.bad_samples += 1;
            }
            unoccluded += first.unoccluded;
            if s == 0 {
                cell = first.surface_cell;
                material = first.material_id;
            }
            if first.material_id != 0 {
                hits += 1;
                depth_sum += first.depth;
                if first.albedo.is_finite() {
                    albedo += first.albedo;
                }
                normal += first.normal;
                glints += u32::from(first.glitter);
            }
        }
        let n = f64::from(spp);
        row.rgb.push(to_f32x3(sum / n));
        row.alpha.push((f64::from(hits) / n) as f32);
        row.albedo.push(to_f32x3(albedo / n));
        row.normal.push(to_f32x3(normal / n));
        row.depth.push(if hits > 0 {
            (depth_sum / f64::from(hits)) as f32
        } else {
            f32::INFINITY
        });
        row.surface_cell.push(cell);
        row.glitter.push((f64::from(glints) / n) as f32);
        row.material_id.push(material);
        row.ao.push((unoccluded / n) as f32);
    }
    row
}

/// Rows rendered per parallel band: the film grows band by band, so the
/// per-row buffers never hold more than this many rows (memory stays near
/// one film), and a cancellation is noticed within a band.
pub const ROWS_PER_BAND: u32 = 32;

/// Renders the film on the current rayon pool. `progress` is called with
/// each finished row's number of pixels (from any thread, in any order).
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
/// by Ctrl-C. Rows already started finish; no partial film is returned.
pub fn render_cancellable(
    scene: &RenderScene,
    camera: &PinholeCamera,
    settings: &FilmSettings,
    progress: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> Option<Film> {
    let pixels = settings.width as usize * settings.height as usize;
    let mut film = Film {
        width: settings.width,
        height: settings.height,
        rgb: Vec::with_capacity(pixels),
        alpha: Vec::with_capacity(pixels),
        albedo: Vec::with_capacity(pixels),
        normal: Vec::with_capacity(pixels),
        depth: Vec::with_capacity(pixels),
        surface_cell: Vec::with_capacity(pixels),
        glitter: Vec::with_capacity(pixels),
        material_id: Vec::with_capacity(pixels),
        ao: Vec::with_capacity(pixels),
        stats: RenderStats::default(),
    };
    let band = ROWS_PER_BAND.max(4 * rayon::current_num_threads() as u32);
    let mut first_row = 0;
    while first_row < settings.height {
        let end = (first_row + band).min(settings.height);
        let rows: Vec<Option<Row>> = (first_row..end)
            .into_par_iter()
            .map(|y| {
                if cancel.load(Ordering::Relaxed) {
                    return None;
                }
                let row = render_row(scene, camera, settings, y);
                progress(u64::from(settings.width));
                Some(row)
            })
            .collect();
        for row in rows {
            let row = row?;
            film.rgb.extend(row.rgb);
            film.alpha.extend(row.alpha);
            film.albedo.extend(row.albedo);
            film.normal.extend(row.normal);
            film.depth.extend(row.depth);
            film.surface_cell.extend(row.surface_cell);
            film.glitter.extend(row.glitter);
            film.material_id.extend(row.material_id);
            film.ao.extend(row.ao);
            film.stats.traced_rays += row.stats.traced_rays;
            film.stats.shadow_rays += row.stats.shadow_rays;
            film.stats.bad_samples += row.stats.bad_samples;
        }
        if cancel.load(Ordering::Relaxed) {
            return None;
        }
        first_row = end;
    }
    Some(film)
}
