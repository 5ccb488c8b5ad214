//! `furfit view`: write the real-time viewer page, serve it, or render its still
//! ([`crate::view`]).

use crate::render::output;
use crate::render::Image;
use crate::view::{self, lights, page, prt, reference, serve, shells::FurSpec, still, View};
use anyhow::Context;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
/// Arguments of `furfit view` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// Fit files (or parameter files, presets) to show, any model; one species each.
    #[arg(long, num_args = 1.., value_name = "FIT")]
    pub params: Vec<String>,
    /// The page's folder; with --still a PNG file; with --reference a report folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the page into an --out that holds other files too (an earlier view's own
    /// files are replaced without it).
    #[arg(long)]
    pub force: bool,
    /// Serve the page in DIR on 127.0.0.1 and print its URL (nothing else is done).
    #[arg(long, value_name = "DIR")]
    pub serve: Option<PathBuf>,
    /// Port for --serve (0 = any free port).
    #[arg(long, default_value_t = 8000)]
    pub port: u16,
    /// Render the page's view on the CPU into --out (PNG), through the same textures.
    #[arg(long)]
    pub still: bool,
    /// Path-trace the same fibers and write PRT-vs-reference errors into --out (yan2017 fits).
    #[arg(long)]
    pub reference: bool,
    /// With --reference: the error's decomposition instead (SH truncation: the transfer
    /// integrated against the light directly; visibility: PRT and path tracer both
    /// without shadowing; each shadowing with its own), into --out/decompose.{md,csv}.
    #[arg(long)]
    pub decompose: bool,
    /// Which fibers shadow in the transfer: others (a fiber never shadows itself), all
    /// (the shells' density as is, seed 003 Eq. 4), off.
    #[arg(long, default_value = "others")]
    pub shadowing: String,
    /// Species shown by --still: index into --params (0-based) or name.
    #[arg(long, default_value = "0")]
    pub species: String,
    /// Light of --still: lobe or sky.
    #[arg(long, default_value = "lobe")]
    pub light: String,
    /// Image size of --still and --reference.
    #[arg(long, default_value = "640x480")]
    pub size: String,
    /// Camera elevation,azimuth in degrees.
    #[arg(long, value_name = "ELEV,AZIM")]
    pub cam: Option<String>,
    /// Camera distance from the middle of the fur (tile sides; the page's wheel zoom).
    #[arg(long, default_value_t = 2.2)]
    pub dist: f64,
    /// --still without the fins at the swatch's borders (the page's fins checkbox).
    #[arg(long)]
    pub no_fins: bool,
    /// Light elevation,azimuth in degrees (default: the light's own).
    #[arg(long, value_name = "ELEV,AZIM")]
    pub light_dir: Option<String>,
    /// Exposure in EV.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub ev: f64,
    /// Texels per tile side of the shell textures.
    #[arg(long, default_value_t = 128)]
    pub res: usize,
    /// Shells of the fur volume.
    #[arg(long, default_value_t = 32)]
    pub shells: usize,
    /// Fibers per tile.
    #[arg(long, default_value_t = 4000)]
    pub fibers: usize,
    /// Fiber length in tile sides.
    #[arg(long, default_value_t = 0.26)]
    pub length: f64,
    /// Helical curl radius in tile sides.
    #[arg(long, default_value_t = 0.006)]
    pub curl: f64,
    /// Comb tilt from the vertical, degrees.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub tilt: f64,
    /// Seed of the fur tile's fibers.
    #[arg(long, default_value_t = 3)]
    pub seed: u64,
    /// Transfer sweep directions NZxNPHI (even NZ).
    #[arg(long, default_value = "8x16")]
    pub dirs: String,
    /// Samples per pixel of --reference.
    #[arg(long, default_value_t = 256)]
    pub spp: usize,
}

fn pair(opt: &str, s: &str) -> anyhow::Result<(f64, f64)> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| anyhow::anyhow!("{opt} '{s}': expected two numbers A,B"))?;
    let n = |v: &str| super::number(v).map_err(|e| anyhow::anyhow!("{opt} '{s}': {e}"));
    Ok((n(a)?, n(b)?))
}

fn fur(a: &Args) -> FurSpec {
    FurSpec {
        res: a.res,
        shells: a.shells,
        fibers: a.fibers,
        length: a.length,
        curl: a.curl,
        tilt_deg: a.tilt,
        seed: a.seed,
        ..FurSpec::default()
    }
}

fn view_of(a: &Args, light: &lights::Light) -> anyhow::Result<View> {
    let mut v = View {
        exposure_ev: a.ev,
        light_elev_deg: light.default_elev,
        light_azim_deg: light.default_azim,
        ..View::default()
    };
    if let Some(c) = &a.cam {
        (v.elev_deg, v.azim_deg) = pair("--cam", c)?;
    }
    if !(a.dist.is_finite() && (0.5..=10.0).contains(&a.dist)) {
        anyhow::bail!(
            "--dist {}: expected 0.5 to 10 (the page's zoom range)",
            a.dist
        );
    }
    v.dist = a.dist;
    if let Some(c) = &a.light_dir {
        (v.light_elev_deg, v.light_azim_deg) = pair("--light-dir", c)?;
    }
    Ok(v)
}

/// Run `furfit view`.
pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(dir) = &a.serve {
        let listener = serve::bind(dir, a.port)?;
        let addr = listener.local_addr().context("--serve")?;
        println!(
            "serving {} at {}  (Ctrl-C to stop)",
            dir.display(),
            serve::url(addr)
        );
        use std::io::Write;
        std::io::stdout().flush().ok();
        return Ok(serve::run(dir, listener)?);
    }
    if a.params.is_empty() {
        anyhow::bail!("--params: give at least one fit file (or --serve DIR)");
    }
    let out = a
        .out
        .clone()
        .ok_or_else(|| anyhow::anyhow!("--out is required"))?;
    let dirs = parse_dirs(&a.dirs)?;
    let (w, h) = super::parse_size("--size", &a.size, 8192, 1 << 24)?;
    if a.still {
        crate::io::check_out_file(&out).context("--out")?;
    } else if a.reference {
        crate::io::check_out_dir(&out).context("--out")?;
    } else {
        page::check_out(&out, a.force).context("--out")?;
    }
    let shadowing = prt::Shadowing::parse(&a.shadowing)?;
    let data = view::build(
        &fur(&a),
        &a.params,
        prt::TableSize::default(),
        dirs,
        shadowing,
    )?;
    for s in &data.species {
        println!(
            "{}: {} ({}), BCSDF table {:.2} s, colour: {}",
            s.name, s.model, s.title, s.seconds, s.colour
        );
    }
    println!(
        "shells: {} x {}^2 texels, {} fibers; coverage {:.2} s, transfer ({} directions, shadowing {}) {:.2} s, packing {:.2} s",
        data.fur.shells, data.fur.res, data.fur.fibers, data.seconds[0], data.n_dirs, data.shadowing.name(), data.seconds[1], data.seconds[2]
    );
    if a.still {
        let species = species_index(&data, &a.species)?;
        let light = lights::by_name(&a.light)?;
        let st = still::Still {
            width: w,
            height: h,
            view: view_of(&a, &light)?,
            species,
            light,
            background: true,
            fins: !a.no_fins,
        };
        let img = still::render(&data, &st);
        let text = [
            ("Software", format!("furfit {}", env!("CARGO_PKG_VERSION"))),
            (
                "Description",
                format!(
                    "furfit view --still: {} under {}",
                    data.species[species].name, light.name
                ),
            ),
        ];
        let bytes = output::png_bytes(&img, st.view.exposure_ev, &text, &out)?;
        crate::io::write_atomic(&out, &bytes)?;
        println!("wrote {}", out.display());
        return Ok(());
    }
    if a.reference && a.decompose {
        let views = lights::LIGHTS
            .iter()
            .map(|l| view_of(&a, l))
            .collect::<anyhow::Result<Vec<_>>>()?;
        let traced = data
            .species
            .iter()
            .zip(&a.params)
            .map(|(sp, spec)| traced_fur(spec, sp))
            .collect::<anyhow::Result<Vec<_>>>()?;
        return super::view_decompose::run(&super::view_decompose::Job {
            data: &data,
            out: &out,
            size: (w, h),
            spp: a.spp,
            dirs,
            views,
            traced,
        });
    }
    if a.reference {
        return run_reference(&a, &data, &out, (w, h));
    }
    let light = lights::LIGHTS[0];
    let files = page::write(&out, &data, &view_of(&a, &light)?)?;
    let size: u64 = files
        .iter()
        .filter_map(|f| std::fs::metadata(f).ok())
        .map(|m| m.len())
        .sum();
    println!(
        "wrote {} ({:.1} MB); open {} or run furfit view --serve {}",
        out.display(),
        size as f64 / 1e6,
        out.join("index.html").display(),
        out.display()
    );
    Ok(())
}

fn species_index(data: &view::ViewData, s: &str) -> anyhow::Result<usize> {
    if let Ok(i) = s.parse::<usize>() {
        if i < data.species.len() {
            return Ok(i);
        }
    }
    data.species
        .iter()
        .position(|sp| sp.name == s)
        .ok_or_else(|| {
            let names: Vec<&str> = data.species.iter().map(|s| s.name.as_str()).collect();
            anyhow::anyhow!(
                "--species {s}: expected an index below {} or one of {}",
                data.species.len(),
                names.join(", ")
            )
        })
}

/// PRT stills against path-traced references, per species and light: PNGs and a table.
fn run_reference(
    a: &Args,
    data: &view::ViewData,
    out: &Path,
    (w, h): (usize, usize),
) -> anyhow::Result<()> {
    let mut files = packing_report(a, data, out, (w, h))?;
    let margin = 0.6;
    let bvh = reference::geometry(data, margin);
    let mut rows = vec![
        "| species | light | PRT vs single PT, 4 px | 16 px | means | PT noise, 4 px | 16 px | PRT vs full PT, 4 px | 16 px | means | PT seconds |".to_string(),
        "|---|---|---|---|---|---|---|---|---|---|---|".to_string(),
    ];
    let mut csv = String::from(
        "species,light,rel_rmse_single_1px,rel_rmse_single_4px,rel_rmse_single_16px,mean_bias_single,pt_noise_4px,pt_noise_16px,rel_rmse_full_4px,rel_rmse_full_16px,mean_bias_full,pt_seconds\n",
    );
    for (i, (sp, spec)) in data.species.iter().zip(&a.params).enumerate() {
        let Some((fp, tint)) = traced_fur(spec, sp)? else {
            continue;
        };
        for light in lights::LIGHTS {
            let v = view_of(a, &light)?;
            let st = still::Still {
                width: w,
                height: h,
                view: v,
                species: i,
                light,
                background: matches!(light.kind, lights::Kind::Sky { .. }),
                // The comparison is inside the swatch, away from its borders.
                fins: false,
            };
            let prt_img = still::render(data, &st);
            let rs = |single, seed| reference::RefSettings {
                width: w,
                height: h,
                spp: a.spp,
                seed,
                single,
                shadows: true,
                margin,
            };
            let t0 = std::time::Instant::now();
            let single = reference::render(&bvh, data, &fp, tint, &light, &v, &rs(true, 11))?;
            let secs = t0.elapsed().as_secs_f64();
            // A second, independent single-scattering image: its distance to the first
            // is the reference's own noise (the floor under any PRT error).
            let single2 = reference::render(&bvh, data, &fp, tint, &light, &v, &rs(true, 12))?;
            let full = reference::render(&bvh, data, &fp, tint, &light, &v, &rs(false, 11))?;
            let mask = reference::mask(data, &v, w, h, -0.1);
            let e = |img: &Image, k| reference::relative_rmse(&prt_img, img, &mask, k);
            let bias = |img: &Image| reference::mean_ratio(&prt_img, img, &mask) - 1.0;
            let (s1, s4, s16, sb) = (e(&single, 1), e(&single, 4), e(&single, 16), bias(&single));
            let noise = |k| reference::relative_rmse(&single2, &single, &mask, k);
            let (n4, n16) = (noise(4), noise(16));
            let (f4, f16, fb) = (e(&full, 4), e(&full, 16), bias(&full));
            let pc = |x: f64| format!("{:.1} %", 100.0 * x);
            let spc = |x: f64| format!("{:+.1} %", 100.0 * x);
            println!(
                "{} / {}: PRT vs single-scattering PT {} (4x4 px blocks), {} (16x16), means {}; PT noise {} / {}; vs full PT {} / {}, means {}",
                sp.name, light.name, pc(s4), pc(s16), spc(sb), pc(n4), pc(n16), pc(f4), pc(f16), spc(fb)
            );
            rows.push(format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} |",
                sp.name,
                light.name,
                pc(s4),
                pc(s16),
                spc(sb),
                pc(n4),
                pc(n16),
                pc(f4),
                pc(f16),
                spc(fb),
                secs
            ));
            csv.push_str(&format!(
                "{},{},{s1:.5},{s4:.5},{s16:.5},{sb:.5},{n4:.5},{n16:.5},{f4:.5},{f16:.5},{fb:.5},{secs:.1}\n",
                sp.name, light.name
            ));
            for (tag, img) in [
                ("prt", &prt_img),
                ("pt_single", &single),
                ("pt_full", &full),
            ] {
                let p = out.join(format!("{}_{}_{tag}.png", sp.name, light.name));
                files.push((
                    p.clone(),
                    output::png_bytes(
                        img,
                        v.exposure_ev,
                        &[("Software", "furfit view --reference".into())],
                        &p,
                    )?,
                ));
            }
        }
    }
    let md = format!("{}\n", rows.join("\n"));
    files.push((out.join("prt_error.md"), md.clone().into_bytes()));
    files.push((out.join("prt_error.csv"), csv.into_bytes()));
    std::fs::create_dir_all(out).with_context(|| format!("--out {}", out.display()))?;
    crate::io::write_atomic_all(&files)?;
    print!("{md}");
    Ok(())
}

/// The fur-model parameters and tint the reference traces a species with; `None` (and a
/// note) for a model the renderer does not trace.
fn traced_fur(
    spec: &str,
    sp: &view::Species,
) -> anyhow::Result<Option<(crate::params::FurParams, crate::render::bsdf::Tint)>> {
    let (mp, _, json) = crate::models::ModelParams::load(spec, None)?;
    let Some(fp) = mp.fur() else {
        println!(
            "{}: {} is not yan2017; the renderer traces the fur model only: skipped",
            sp.name, sp.model
        );
        return Ok(None);
    };
    let tint = json
        .as_ref()
        .and_then(|v| crate::params::fit_channels(v, spec).ok())
        .and_then(|c| crate::render::bsdf::Tint::from_fit_channels(&c))
        .unwrap_or_default();
    Ok(Some((fp, tint)))
}

/// The packing's own error, per species and light at the view of `--reference`: the
/// texel radiance `sum_k c_k v_k` from 8-bit textures (what the page uses) and from half
/// floats, against the unquantised transfer ([`crate::view::pack::radiance_error`]).
fn packing_report(
    a: &Args,
    data: &view::ViewData,
    out: &Path,
    (w, h): (usize, usize),
) -> anyhow::Result<Vec<(PathBuf, Vec<u8>)>> {
    let dirs = data.n_dirs;
    let fibers = view::shells::grow(&data.fur);
    let pieces = view::shells::pieces(&data.fur, &fibers);
    let cov = pieces.coverage();
    let (nz, np) = parse_dirs(&a.dirs)?;
    let rule = view::sh::Rule::product(nz, np);
    debug_assert_eq!(rule.dirs.len(), dirs);
    let weights = prt::sh_weights(&rule);
    let t = prt::transfer_pieces(
        &data.fur,
        &pieces,
        &rule,
        data.shadowing,
        &weights,
        view::sh::N_COEFFS,
    );
    let mut md = vec![
        "| species | light | 8-bit, per-shell scale and offset (page) | half float |".to_string(),
        "|---|---|---|---|".to_string(),
    ];
    let mut csv = String::from("species,light,rel_rmse_u8,rel_rmse_f16\n");
    for (i, sp) in data.species.iter().enumerate() {
        for light in lights::LIGHTS {
            let (_, c) = still::lighting(data, i, &light, &view_of(a, &light)?, w, h);
            let (e8, e16) = view::pack::radiance_error(&t, &cov, &data.packed, &c);
            println!(
                "{} / {}: packing error of the texel radiance: 8-bit {:.3} %, half {:.4} %",
                sp.name,
                light.name,
                100.0 * e8,
                100.0 * e16
            );
            md.push(format!(
                "| {} | {} | {:.3} % | {:.4} % |",
                sp.name,
                light.name,
                100.0 * e8,
                100.0 * e16
            ));
            csv.push_str(&format!("{},{},{e8:.6},{e16:.6}\n", sp.name, light.name));
        }
    }
    let bytes8 = data.packed.bytes.len();
    md.push(String::new());
    md.push(format!(
        "Relative RMSE of the texel radiance (coverage-weighted, RGB) against the unquantised transfer. Texture bytes: 8-bit {:.1} MB, half float {:.1} MB ({} shells x {}^2 texels x 28 channels).",
        bytes8 as f64 / 1e6,
        2.0 * bytes8 as f64 / 1e6,
        data.fur.shells,
        data.fur.res
    ));
    Ok(vec![
        (
            out.join("packing.md"),
            format!("{}\n", md.join("\n")).into_bytes(),
        ),
        (out.join("packing.csv"), csv.into_bytes()),
    ])
}

fn parse_dirs(s: &str) -> anyhow::Result<(usize, usize)> {
    let bad = || anyhow::anyhow!("--dirs '{s}': expected NZxNPHI");
    let (nz, np) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let p = |v: &str| v.trim().parse::<usize>().map_err(|_| bad());
    Ok((p(nz)?, p(np)?))
}
