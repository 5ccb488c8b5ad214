//! `furfit view --reference --decompose`: where the PRT's error against the path-traced
//! reference lives (issue 62, `reports/viewer/prt_error.md`). Per species and light, the
//! same view is rendered as
//!
//! * the single-scattering path tracer with and without shadow rays;
//! * the PRT without shadowing (`T = 1`: the BCSDF against the light alone);
//! * for each shadowing (`all`, `others`): the page's PRT (SH, tabulated BCSDF, 8-bit
//!   textures), the same with the BCSDF's SH projection computed at the camera's exact
//!   inclination, and the transfer integrated against the light directly
//!   ([`crate::view::direct`]: same visibility, no SH truncation),
//!
//! and compared pairwise (relative RMSE at 4 and 16 px blocks, mean bias), into
//! `--out/decompose.{md,csv}`.

use crate::params::FurParams;
use crate::render::bsdf::Tint;
use crate::render::{output, Image};
use crate::view::prt::{self, Shadowing};
use crate::view::{self, direct, lights, pack, reference, sh, shells, still, View, ViewData};
use std::path::Path;

/// One comparison's figures: relative RMSE at 4 and 16 px blocks, mean bias.
fn compare(a: &Image, b: &Image, mask: &[bool]) -> [f64; 3] {
    [
        reference::relative_rmse(a, b, mask, 4),
        reference::relative_rmse(a, b, mask, 16),
        reference::mean_ratio(a, b, mask) - 1.0,
    ]
}

/// The unshadowed PRT with the BCSDF's lighting taken at every pixel's own view
/// direction (the page takes the camera-to-target direction for the whole frame): with
/// `T = 1` every fiber texel's radiance is `c_0 sqrt(4 pi)`, so the picture is that
/// radiance times the shells' composited coverage `A`, over the background times `1 - A`.
fn per_pixel_view(
    data: &ViewData,
    st: &still::Still,
    cov: &[Vec<f32>],
    table: &prt::BcsdfTable,
    l: &prt::Rgb25,
) -> Image {
    use rayon::prelude::*;
    let ones: Vec<Vec<[f32; 4]>> = cov
        .iter()
        .map(|c| c.iter().map(|&a| [1.0, 1.0, 1.0, a]).collect())
        .collect();
    let bare = still::Still {
        background: false,
        ..st.clone()
    };
    let a = still::render_tex(data, &bare, &[ones]);
    let cam = still::camera(data, &st.view, st.width, st.height);
    let u = data.fur.comb();
    let k0 = (4.0 * std::f64::consts::PI).sqrt();
    let px: Vec<[f64; 3]> = (0..st.width * st.height)
        .into_par_iter()
        .map(|i| {
            let d = cam.ray_dir((i % st.width) as f64 + 0.5, (i / st.width) as f64 + 0.5);
            let c = prt::frame_lighting(table, l, -d, u);
            let cover = a.data[i][0];
            std::array::from_fn(|ch| {
                let bg = if st.background {
                    sh::reconstruct(&l[ch], [d.x, d.y, d.z])
                } else {
                    0.0
                };
                c[ch][0] * k0 * cover + bg * (1.0 - cover)
            })
        })
        .collect();
    Image {
        width: st.width,
        height: st.height,
        data: px,
    }
}

/// What the decomposition runs on (worked out by `furfit view`'s options).
pub(super) struct Job<'a> {
    pub data: &'a ViewData,
    pub out: &'a Path,
    pub size: (usize, usize),
    pub spp: usize,
    /// The transfer's sweep directions (`--dirs`).
    pub dirs: (usize, usize),
    /// The view of each light ([`lights::LIGHTS`]' order).
    pub views: Vec<View>,
    /// Per species, the fur-model parameters and tint the reference traces, if any.
    pub traced: Vec<Option<(FurParams, Tint)>>,
}

type Row = (String, String, String, [f64; 3]);

pub(super) fn run(job: &Job) -> anyhow::Result<()> {
    let (data, out, (w, h), dirs) = (job.data, job.out, job.size, job.dirs);
    let rule = sh::Rule::product(dirs.0, dirs.1);
    let fibers = shells::grow(&data.fur);
    let pieces = shells::pieces(&data.fur, &fibers);
    let cov = pieces.coverage();
    let shw = prt::sh_weights(&rule);
    let variants = [Shadowing::All, Shadowing::Others];
    // The page's SH transfer per shadowing (it depends on the fur only).
    let packed: Vec<pack::Packed> = variants
        .iter()
        .map(|&sv| {
            let t = prt::transfer_pieces(&data.fur, &pieces, &rule, sv, &shw, sh::N_COEFFS);
            pack::pack_u8(&t, &cov)
        })
        .collect();
    let margin = 0.6;
    let bvh = reference::geometry(data, margin);
    let mut rows: Vec<Row> = Vec::new();
    let mut files = Vec::new();
    for (i, (sp, traced)) in data.species.iter().zip(&job.traced).enumerate() {
        let Some((fp, tint)) = traced else {
            continue;
        };
        for (light, &v) in lights::LIGHTS.iter().zip(&job.views) {
            let light = *light;
            let st = still::Still {
                width: w,
                height: h,
                view: v,
                species: i,
                light,
                background: matches!(light.kind, lights::Kind::Sky { .. }),
                fins: false,
            };
            let (l, c) = still::lighting(data, i, &light, &v, w, h);
            let cam = still::camera(data, &v, w, h);
            let wo = (cam.eye - view::target(&data.fur)).normalized();
            let dl = direct::lighting(&sp.channels, &l, wo, data.fur.comb(), dirs, (180, 360));
            let rs = |shadows| reference::RefSettings {
                width: w,
                height: h,
                spp: job.spp,
                seed: 11,
                single: true,
                shadows,
                margin,
            };
            let pt_on = reference::render(&bvh, data, fp, *tint, &light, &v, &rs(true))?;
            let pt_off = reference::render(&bvh, data, fp, *tint, &light, &v, &rs(false))?;
            let mask = reference::mask(data, &v, w, h, -0.1);
            let direct_img = |sv| {
                let t = prt::transfer_pieces(&data.fur, &pieces, &rule, sv, &dl.cells, 3);
                still::render_tex(data, &st, &[direct::texels(&t, &cov)])
            };
            let prt_off = direct_img(Shadowing::Off);
            let mut save = |tag: &str, img: &Image| -> anyhow::Result<()> {
                let p = out.join(format!("{}_{}_{tag}.png", sp.name, light.name));
                let sw = [("Software", "furfit view --reference --decompose".into())];
                files.push((p.clone(), output::png_bytes(img, v.exposure_ev, &sw, &p)?));
                Ok(())
            };
            save("pt_single", &pt_on)?;
            save("pt_unshadowed", &pt_off)?;
            save("prt_off", &prt_off)?;
            let mut push = |what: String, f: [f64; 3]| {
                println!(
                    "{} / {}: {what}: {:.1} % (4 px), {:.1} % (16 px), means {:+.1} %",
                    sp.name,
                    light.name,
                    100.0 * f[0],
                    100.0 * f[1],
                    100.0 * f[2]
                );
                rows.push((sp.name.clone(), light.name.into(), what, f));
            };
            push(
                "PT shadowed vs PT unshadowed".into(),
                compare(&pt_on, &pt_off, &mask),
            );
            push(
                "PRT off vs PT unshadowed".into(),
                compare(&prt_off, &pt_off, &mask),
            );
            let pix = per_pixel_view(data, &st, &cov, &sp.table, &l);
            save("prt_off_per_pixel_view", &pix)?;
            push(
                "PRT off, each pixel's own view direction, vs PT unshadowed".into(),
                compare(&pix, &pt_off, &mask),
            );
            for (vi, &sv) in variants.iter().enumerate() {
                let n = sv.name();
                let tex = |c: &prt::Rgb25| still::texel_radiance(&packed[vi], c);
                let centre = still::render_tex(data, &st, &[tex(&c)]);
                let exact = still::render_tex(data, &st, &[tex(&dl.c)]);
                let cl = still::corner_lighting(data, i, &light, &v, w, h);
                let page = still::render_tex(data, &st, &cl.map(|c| tex(&c)));
                let dir = direct_img(sv);
                save(&format!("prt_{n}"), &page)?;
                push(
                    format!("PRT {n}: SH (exact BCSDF projection) vs direct (SH truncation)"),
                    compare(&exact, &dir, &mask),
                );
                push(
                    format!("PRT {n}: SH centre view vs SH exact (BCSDF table)"),
                    compare(&centre, &exact, &mask),
                );
                push(
                    format!("PRT {n}: direct vs PRT off (PRT shadowing)"),
                    compare(&dir, &prt_off, &mask),
                );
                push(
                    format!("PRT {n}: direct vs PT shadowed"),
                    compare(&dir, &pt_on, &mask),
                );
                push(
                    format!("PRT {n}: SH, one view direction per frame, vs PT shadowed"),
                    compare(&centre, &pt_on, &mask),
                );
                push(
                    format!("PRT {n}: SH page (corners' view directions) vs PT shadowed"),
                    compare(&page, &pt_on, &mask),
                );
            }
        }
    }
    write(out, &rows, files)
}

/// `decompose.{md,csv}` and the PNGs into `out`.
fn write(
    out: &Path,
    rows: &[Row],
    mut files: Vec<(std::path::PathBuf, Vec<u8>)>,
) -> anyhow::Result<()> {
    let mut md = vec![
        "| species | light | comparison | rel. RMSE 4 px | 16 px | means |".to_string(),
        "|---|---|---|---|---|---|".to_string(),
    ];
    let mut csv = String::from("species,light,comparison,rel_rmse_4px,rel_rmse_16px,mean_bias\n");
    for (s, l, what, f) in rows {
        md.push(format!(
            "| {s} | {l} | {what} | {:.1} % | {:.1} % | {:+.1} % |",
            100.0 * f[0],
            100.0 * f[1],
            100.0 * f[2]
        ));
        csv.push_str(&format!(
            "{s},{l},{what},{:.5},{:.5},{:.5}\n",
            f[0], f[1], f[2]
        ));
    }
    let md = format!("{}\n", md.join("\n"));
    std::fs::create_dir_all(out)?;
    files.push((out.join("decompose.md"), md.clone().into_bytes()));
    files.push((out.join("decompose.csv"), csv.into_bytes()));
    crate::io::write_atomic_all(&files)?;
    print!("{md}");
    Ok(())
}
