//! `furfit render`: a small CPU path tracer that previews fitted fur on a built-in lock of
//! curved fibers, with the near-field, far-field or multi-scale BCSDF of [`crate::model`].
//!
//! * [`scene`]: the procedural lock, camera, lights;
//! * [`bvh`]: BVH over fiber segments, ray vs camera-facing ribbon, offset `h`;
//! * [`bsdf`]: the renderer's BCSDF (units, frame, importance sampling, exact pdfs);
//! * [`integrator`]: path tracing with NEE to the key light (a delta light: no MIS to
//!   weigh), the environment by BCSDF sampling or with `--env-nee` by NEE + MIS, Russian
//!   roulette, pixel footprint;
//! * [`output`]: tone mapping, PNG/EXR/AOV writing, contact sheets;
//! * [`study`]: convergence and culling studies; [`study_run`]: one
//!   `furfit render-convergence` run (the study of its options, its report files);
//! * [`batch`]: one `furfit render` run (its images, their files, the contact sheet).
//!
//! Determinism: every pixel has its own RNG (and with `--pixel-sampling` its own stream
//! seeds, [`qmc`]) seeded from (`seed`, pixel index), so an image
//! depends on the seed only, not on the number of threads.

// Per-channel / per-lobe loops over fixed [_; 3] and [_; 5] arrays index several arrays at
// once, as the formulas do; iterator chains would obscure them.
#![allow(clippy::needless_range_loop)]

pub mod batch;
pub mod bsdf;
pub mod bvh;
pub mod furnace;
pub mod integrator;
pub mod ishair;
pub mod math;
pub mod model_bsdf;
pub mod ntable;
pub mod output;
pub mod qmc;
pub mod sampler_study;
pub mod scene;
pub mod select;
pub mod strand;
pub mod strand_albedo;
pub mod strand_train;
pub mod study;
pub mod study_run;

#[cfg(test)]
mod bsdf_tests;

use crate::model::LobeSet;
use crate::params::FurParams;
use bsdf::{FiberBsdf, Mode, Tint};
use bvh::{Bvh, DirTree};
use integrator::{Bcsdf, Integrator};
use math::{Rgb, V3};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use scene::{Camera, DirectionalLight, Environment, StrandSpec};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Largest samples per pixel accepted (`render --spp`, `render-convergence --max-spp`,
/// `--ref-spp`): far above any preview or reference here, and it stops a typo (or
/// `u64::MAX`) from running for ever.
pub const MAX_SPP: usize = 1 << 20;
/// Largest path length (`--max-depth`): Russian roulette ends nearly every path long
/// before it; more only lets a typo through.
pub const MAX_DEPTH: usize = 1024;
/// Largest image side in pixels (`--size`, `--frame`).
pub const MAX_SIDE: usize = 8192;
/// Most pixels of one image (`--size`): a render holds ~300 bytes per pixel (beauty, five
/// AOVs, accumulators), so 4096 x 4096 is ~5 GB; 8192 x 8192 (~20 GB) would abort on a
/// 24 GB machine instead of failing with a message.
pub const MAX_PIXELS: usize = 1 << 24;
/// Largest key-light irradiance / environment radiance: with the exposure bound
/// ([`output::MAX_EXPOSURE_EV`]) pixel values stay far inside the range where the tone
/// map is finite (beyond it the ACES fit turns to inf/inf = NaN, an all-black image).
pub const MAX_RADIANCE: f64 = 1e6;

/// A linear RGB image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Pixels, row-major, top row first.
    pub data: Vec<Rgb>,
}

impl Image {
    /// A black image of `width x height`.
    pub fn new(width: usize, height: usize) -> Image {
        Image {
            width,
            height,
            data: vec![[0.0; 3]; width * height],
        }
    }

    /// Root-mean-square difference over all pixels and channels.
    pub fn rmse(&self, other: &Image) -> f64 {
        let n = (self.data.len() * 3).max(1) as f64;
        let s: f64 = self
            .data
            .iter()
            .zip(&other.data)
            .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).powi(2)))
            .sum();
        (s / n).sqrt()
    }

    /// The largest channel value of any pixel (for scaling previews).
    pub fn max_value(&self) -> f64 {
        self.data
            .iter()
            .flat_map(|p| p.iter().copied())
            .fold(0.0, f64::max)
    }
}

/// Camera placement (degrees for angles).
#[derive(Clone, Debug)]
pub struct CameraSpec {
    /// Distance from the camera's target (world units).
    pub dist: f64,
    /// Elevation above the horizontal plane, degrees.
    pub elev_deg: f64,
    /// Azimuth about the vertical axis, degrees.
    pub azim_deg: f64,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
}

impl Default for CameraSpec {
    fn default() -> Self {
        CameraSpec {
            dist: 3.0,
            elev_deg: 10.0,
            azim_deg: 0.0,
            fov_deg: 26.0,
        }
    }
}

/// Everything that defines one render.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Samples (camera paths) per pixel.
    pub spp: usize,
    /// Seed of every pixel's random stream (renders do not depend on the thread count).
    pub seed: u64,
    /// Worker threads (0 = rayon's default).
    pub threads: usize,
    /// Which scale of the model shading uses (`--mode`).
    pub mode: Mode,
    /// The lobes rendered (others 0).
    pub lobes: LobeSet,
    /// Fiber vertices a path may have at most.
    pub max_depth: usize,
    /// [`Integrator::roulette_from`] (default 2).
    pub roulette_from: usize,
    /// [`Integrator::footprint_scale`].
    pub footprint_scale: f64,
    /// [`Integrator::secondary_spread`].
    pub secondary_spread: f64,
    /// Where the camera stands.
    pub camera: CameraSpec,
    /// The key light, if any.
    pub light: Option<DirectionalLight>,
    /// The environment (sky) light.
    pub env: Environment,
    /// The procedural lock rendered.
    pub strand: StrandSpec,
    /// Per-channel absorption (a fit's r, g, b colour or ratios).
    pub tint: Tint,
    /// Render only this window `(x0, y0, w, h)` of the full frame.
    pub region: Option<(usize, usize, usize, usize)>,
    /// Cull far-field / multi-scale segments that cannot reach the queried azimuth
    /// (`FarOptions::cull`).
    pub far_cull: bool,
    /// Serve far-field / multi-scale queries from a per-render table
    /// ([`ntable`]); `false` runs the analytic engine per query (exact, much slower).
    pub far_table: bool,
    /// Next-event estimation of the environment with MIS ([`Integrator::env_nee`]).
    pub env_nee: bool,
    /// How the scattered lobes' `M_s` is read ([`bsdf::MedullaEnergy`]).
    pub medulla_energy: bsdf::MedullaEnergy,
    /// Weights file of [`bsdf::MedullaEnergy::Strand`] (`None`: the built-in ones).
    pub energy_weights: Option<std::path::PathBuf>,
    /// The BCSDF sampler's proposal ([`ishair::Sampling`]).
    pub sampling: ishair::Sampling,
    /// Where the pixel position and the first vertices' BCSDF uniforms come from
    /// ([`qmc::PixelSampling`]).
    pub pixel_sampling: qmc::PixelSampling,
    /// Set from another thread, ends the render with [`crate::Error::Interrupted`] after
    /// the image rows in progress (the default token is never set).
    pub cancel: crate::cancel::Cancel,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 512,
            height: 512,
            spp: 64,
            seed: 1,
            threads: 0,
            mode: Mode::Multiscale,
            lobes: LobeSet::ALL,
            max_depth: 16,
            roulette_from: 2,
            footprint_scale: 1.0,
            secondary_spread: 1.0,
            camera: CameraSpec::default(),
            light: Some(DirectionalLight {
                dir: V3::new(-0.5, 0.6, 0.62).normalized(),
                irradiance: [2.5; 3],
            }),
            env: Environment {
                top: [0.32, 0.34, 0.38],
                bottom: [0.10, 0.10, 0.10],
            },
            strand: StrandSpec::default(),
            tint: Tint::default(),
            region: None,
            far_cull: true,
            far_table: true,
            env_nee: false,
            medulla_energy: bsdf::MedullaEnergy::Strand,
            energy_weights: None,
            sampling: ishair::Sampling::default(),
            pixel_sampling: qmc::PixelSampling::default(),
            cancel: Default::default(),
        }
    }
}

/// A rendered frame: beauty, per-lobe AOVs (first fiber vertex) and statistics.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// The full path radiance per pixel.
    pub beauty: Image,
    /// Indexed by [`crate::model::Lobe::index`].
    pub lobes: [Image; 5],
    /// Rays traced (closest-hit and shadow).
    pub rays: u64,
    /// Seconds tracing paths (excludes `setup_seconds`).
    pub seconds: f64,
    /// Seconds of setup before tracing: the far-field table (when one is built), the
    /// lobe-selection table and the shadow-ray tree (when not cached by the scene).
    pub setup_seconds: f64,
}

impl RenderOutput {
    /// Rays per second of tracing (`rays / seconds`).
    pub fn rays_per_second(&self) -> f64 {
        self.rays as f64 / self.seconds.max(1e-9)
    }
}

/// What a far-field table depends on: parameters, tint, lobes and the culling flag.
type TableKey = ([u64; 10], [u64; 7], LobeSet, bool);

/// Prepared scene (geometry is reused across renders of a study), with the far-field
/// tables of the parameter sets rendered so far (a study renders one set many times).
pub struct Scene {
    /// The lock's acceleration structure.
    pub bvh: Bvh,
    tables: Mutex<Vec<(TableKey, Arc<ntable::FarTable>)>>,
    /// Shadow-ray trees of the key light directions rendered so far.
    light_trees: Mutex<Vec<([u64; 3], Arc<DirTree>)>>,
    /// Strand energy scales of the parameter sets rendered so far.
    energies: Mutex<Vec<(EnergyKey, Arc<strand::EnergyScale>)>>,
}

/// What a Strand energy scale depends on: parameters, tint, weights file.
type EnergyKey = ([u64; 10], [u64; 7], Option<std::path::PathBuf>);

impl Scene {
    /// The scene of lock `strand` (builds its BVH).
    pub fn build(strand: &StrandSpec) -> Scene {
        Scene {
            bvh: Bvh::build(scene::build_lock(strand)),
            tables: Default::default(),
            light_trees: Default::default(),
            energies: Default::default(),
        }
    }

    /// The tree for shadow rays toward a directional light along `dir` (built on first
    /// use; [`DirTree`]).
    pub fn light_tree(&self, dir: V3) -> Arc<DirTree> {
        let key = [dir.x, dir.y, dir.z].map(f64::to_bits);
        cached(&self.light_trees, key, || self.bvh.dir_tree(dir))
    }

    /// Set the Strand energy scale of `bsdf` ([`bsdf::MedullaEnergy::Strand`]), built on
    /// first use for its key; an unreadable weights file is an error.
    fn energy(
        &self,
        bsdf: &mut FiberBsdf,
        params: &FurParams,
        s: &RenderSettings,
    ) -> crate::Result<()> {
        if !bsdf.lobes().contains(crate::model::Lobe::TTs)
            && !bsdf.lobes().contains(crate::model::Lobe::TRTs)
        {
            return Ok(());
        }
        let key: EnergyKey = (param_bits(params), s.tint.key(), s.energy_weights.clone());
        let mut entries = self.energies.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, v)) = entries.iter().find(|(k, _)| *k == key) {
            bsdf.energy = Some(v.clone());
            return Ok(());
        }
        let mlp = match &s.energy_weights {
            Some(p) => strand::StrandMlp::load(p)?,
            None => strand::StrandMlp::builtin()?,
        };
        let v = Arc::new(strand::EnergyScale::build(params, s.tint, &mlp));
        entries.push((key, v.clone()));
        bsdf.energy = Some(v);
        Ok(())
    }

    /// Set the far-field table of `bsdf`, built on first use for its key.
    fn far_table(&self, bsdf: &mut FiberBsdf, params: &FurParams, s: &RenderSettings) {
        let key: TableKey = (param_bits(params), s.tint.key(), bsdf.lobes(), s.far_cull);
        let table = cached(&self.tables, key, || bsdf.tabulate_far());
        bsdf.far_table = Some(table);
    }
}

/// The value of a scene cache under `key`, built by `build` on first use (under the lock,
/// so concurrent renders build it once).
fn cached<K: PartialEq, V>(
    cache: &Mutex<Vec<(K, Arc<V>)>>,
    key: K,
    build: impl FnOnce() -> V,
) -> Arc<V> {
    let mut entries = cache.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, v)) = entries.iter().find(|(k, _)| *k == key) {
        return v.clone();
    }
    let v = Arc::new(build());
    entries.push((key, v.clone()));
    v
}

/// Bit patterns of the ten parameters (a cache key).
fn param_bits(params: &FurParams) -> [u64; 10] {
    [
        params.eta,
        params.kappa,
        params.alpha,
        params.beta_m,
        params.beta_n,
        params.sigma_c_a,
        params.sigma_m_s,
        params.sigma_m_a,
        params.g,
        params.l,
    ]
    .map(f64::to_bits)
}

fn pixel_seed(seed: u64, index: u64) -> u64 {
    // SplitMix64 finaliser of (seed, index).
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(index.wrapping_mul(0xBF58_476D_1CE4_E5B9))
        .wrapping_add(0x94D0_49BB_1331_11EB);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Render `params` with `settings` (builds the scene).
pub fn render(params: &FurParams, settings: &RenderSettings) -> crate::Result<RenderOutput> {
    let scene = Scene::build(&settings.strand);
    render_scene(&scene, params, settings)
}

/// Render with a prepared scene.
pub fn render_scene(
    scene: &Scene,
    params: &FurParams,
    s: &RenderSettings,
) -> crate::Result<RenderOutput> {
    params.validate()?;
    frame_pool(s)?.install(|| render_in_pool(scene, params, s))
}

/// The thread pool of a frame of `s`, once its size and spp are checked.
fn frame_pool(s: &RenderSettings) -> crate::Result<rayon::ThreadPool> {
    if s.width == 0 || s.height == 0 || s.spp == 0 {
        return Err(crate::Error::Invalid(
            "image size and spp must be positive".into(),
        ));
    }
    // A pixel's stratified samples are numbered in 32 bits ([`qmc::PixelSample`]).
    if s.spp > MAX_SPP {
        return Err(crate::Error::Invalid(format!(
            "spp {} is above the largest accepted, {MAX_SPP}",
            s.spp
        )));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(s.threads)
        .build()
        .map_err(|e| crate::Error::Invalid(format!("thread pool: {e}")))
}

/// The frame of `s` through `bsdf`: the light tree, camera and integrator of the scene,
/// `setup` the clock started before the BCSDF's own set-up (counted in the output's
/// set-up time).
fn trace_scene<B: Bcsdf>(
    scene: &Scene,
    bsdf: &B,
    s: &RenderSettings,
    setup: Instant,
) -> crate::Result<RenderOutput> {
    let light_tree = s.light.map(|l| scene.light_tree(l.dir));
    let setup_seconds = setup.elapsed().as_secs_f64();
    let camera = Camera::look_at(
        V3::new(0.0, 0.0, 0.0),
        s.camera.dist,
        s.camera.elev_deg,
        s.camera.azim_deg,
        s.camera.fov_deg,
        s.width,
        s.height,
    );
    let integ = Integrator {
        bvh: &scene.bvh,
        light_tree: light_tree.as_deref(),
        bsdf,
        camera: &camera,
        light: s.light,
        env: s.env,
        mode: s.mode,
        max_depth: s.max_depth,
        roulette_from: s.roulette_from,
        footprint_scale: s.footprint_scale,
        secondary_spread: s.secondary_spread,
        env_nee: s.env_nee,
    };
    trace_frame(&integ, s, setup_seconds)
}

fn render_in_pool(
    scene: &Scene,
    params: &FurParams,
    s: &RenderSettings,
) -> crate::Result<RenderOutput> {
    let mut bsdf = FiberBsdf::new(params, s.tint, s.lobes);
    bsdf.far_opts.cull = s.far_cull;
    bsdf.medulla_energy = s.medulla_energy;
    bsdf.sampling = s.sampling;
    let setup = Instant::now();
    // Multi-scale with footprint 0 only ever queries the near field.
    let spans = s.mode == Mode::Far || (s.mode == Mode::Multiscale && s.footprint_scale > 0.0);
    if s.far_table && spans {
        scene.far_table(&mut bsdf, params, s);
    }
    // The energy scale first: the lobe selection weighs the scaled lobes.
    if s.medulla_energy == bsdf::MedullaEnergy::Strand {
        scene.energy(&mut bsdf, params, s)?;
    }
    bsdf.build_select_table();
    trace_scene(scene, &bsdf, s, setup)
}

/// Render `rgb`, the parameters of the r, g and b channels of a model other than the fur
/// model, through its renderer BSDF ([`crate::models::FiberModel::render_bsdf`],
/// [`model_bsdf`]): near field only, every lobe, the settings' fur-model options (tint,
/// tables, medulla energy, sampling) unread. A model without a renderer BSDF is an
/// error naming it.
pub fn render_model_scene(
    scene: &Scene,
    rgb: &[crate::models::ModelParams; 3],
    s: &RenderSettings,
) -> crate::Result<RenderOutput> {
    let model = rgb[0].model;
    for p in rgb {
        p.validate()?;
        if p.model.name() != model.name() {
            return Err(crate::Error::Invalid(format!(
                "render: channels of two models ({} and {})",
                model.name(),
                p.model.name()
            )));
        }
    }
    let inner = model
        .render_bsdf([&rgb[0].values, &rgb[1].values, &rgb[2].values])
        .ok_or_else(|| {
            crate::Error::Invalid(format!(
                "furfit render cannot render model {}: it has no renderer BSDF \
                 (renderable: {})",
                model.name(),
                renderable_models().join(", ")
            ))
        })?;
    if s.mode != Mode::Near {
        return Err(crate::Error::Invalid(format!(
            "model {} renders its near field only (--mode near), not --mode {}",
            model.name(),
            s.mode.name()
        )));
    }
    if s.lobes != LobeSet::ALL {
        return Err(crate::Error::Invalid(format!(
            "--lobes names the fur model's lobes: a render of model {} has all of its own",
            model.name()
        )));
    }
    let bsdf = model_bsdf::ModelBsdf { inner };
    // `s.mode` is near (checked above).
    frame_pool(s)?.install(|| trace_scene(scene, &bsdf, s, Instant::now()))
}

/// The registered models `furfit render` renders: the fur model and every model with a
/// renderer BSDF (probed at its first preset).
pub fn renderable_models() -> Vec<&'static str> {
    crate::models::MODELS
        .iter()
        .filter(|m| {
            m.name() == "yan2017"
                || m.presets().first().is_some_and(|p| {
                    crate::models::ModelParams::from_file_units(**m, p.values)
                        .is_ok_and(|q| m.render_bsdf([&q.values, &q.values, &q.values]).is_some())
                })
        })
        .map(|m| m.name())
        .collect()
}

/// Trace every pixel of the settings' frame (or region) with `integ`.
fn trace_frame<B: Bcsdf>(
    integ: &Integrator<'_, B>,
    s: &RenderSettings,
    setup_seconds: f64,
) -> crate::Result<RenderOutput> {
    let (x0, y0, w, h) = s.region.unwrap_or((0, 0, s.width, s.height));
    if x0 + w > s.width || y0 + h > s.height || w == 0 || h == 0 {
        return Err(crate::Error::Invalid(format!(
            "region {x0},{y0} {w}x{h} is outside the {}x{} image",
            s.width, s.height
        )));
    }
    let start = Instant::now();
    let work = || {
        (0..h)
            .into_par_iter()
            .map(|j| {
                let mut row = Vec::with_capacity(w);
                let mut rays = 0u64;
                // Once cancelled, the rows not started yet stay empty (refused below).
                if s.cancel.is_cancelled() {
                    return (row, rays);
                }
                for i in 0..w {
                    let (px, py) = (x0 + i, y0 + j);
                    let idx = (py * s.width + px) as u64;
                    let pixel_seed = pixel_seed(s.seed, idx);
                    let mut rng = Xoshiro256PlusPlus::seed_from_u64(pixel_seed);
                    let kind = s.pixel_sampling;
                    let mut acc = integrator::PathResult::default();
                    for k in 0..s.spp {
                        use rand::Rng;
                        // Past 2^32 samples the index would repeat: still unbiased (each
                        // sample is uniform on its own), and far above MAX_SPP anyway.
                        let q = (kind != qmc::PixelSampling::Independent).then(|| {
                            qmc::PixelSample::new(kind, pixel_seed, k as u32, s.spp as u32)
                        });
                        let [jx, jy] = match &q {
                            Some(q) => q.pair(0, &mut rng),
                            None => [rng.random(), rng.random()],
                        };
                        let r = integ.trace(px as f64 + jx, py as f64 + jy, &mut rng, q.as_ref());
                        for c in 0..3 {
                            acc.beauty[c] += r.beauty[c];
                            for l in 0..5 {
                                acc.lobes[l][c] += r.lobes[l][c];
                            }
                        }
                        rays += r.rays;
                    }
                    let k = 1.0 / s.spp as f64;
                    acc.beauty = acc.beauty.map(|v| v * k);
                    for l in acc.lobes.iter_mut() {
                        *l = l.map(|v| v * k);
                    }
                    row.push(acc);
                }
                (row, rays)
            })
            .collect::<Vec<_>>()
    };
    let rows = work();
    s.cancel.check()?;
    let seconds = start.elapsed().as_secs_f64();
    let mut beauty = Image::new(w, h);
    let mut lobes = std::array::from_fn(|_| Image::new(w, h));
    let mut rays = 0;
    for (j, (row, r)) in rows.into_iter().enumerate() {
        rays += r;
        for (i, p) in row.into_iter().enumerate() {
            beauty.data[j * w + i] = p.beauty;
            for l in 0..5 {
                let img: &mut Image = &mut lobes[l];
                img.data[j * w + i] = p.lobes[l];
            }
        }
    }
    Ok(RenderOutput {
        beauty,
        lobes,
        rays,
        seconds,
        setup_seconds,
    })
}
