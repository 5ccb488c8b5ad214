//! `furfit export --scene`: the preview's test scene ([`crate::render::scene`]: the lock
//! of [`build_lock`], the default camera, directional key light and environment of
//! [`RenderSettings::default`]) around the exported material, as a scene the renderer
//! renders as it is: Mitsuba 3 (scene XML plus the lock as a `bsplinecurve` control-point
//! file beside it) and pbrt-v4 (one file, the lock as `Shape "curve"`s).
//!
//! The fibers are the preview's polylines, taken as B-spline control points (both
//! renderers' curves are smooth; the end points are repeated so each curve reaches its
//! root and tip). furfit's environment is a vertical gradient; the scenes use its mean, a
//! constant.

use super::material::{comment_safe, identifier, Material, Written, MARKER};
use crate::error::{Error, Num, Result};
use crate::render::math::V3;
use crate::render::scene::build_lock;
use crate::render::RenderSettings;
use std::path::{Path, PathBuf};

/// What the scenes share, from the preview's defaults.
pub struct Lock {
    /// Control points `(point, radius)` of every fiber, root to tip.
    pub fibers: Vec<Vec<(V3, f64)>>,
    /// Camera position.
    pub eye: V3,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    /// Unit direction toward the key light, its irradiance (grey).
    pub light_dir: V3,
    /// Irradiance of the key light (grey), at normal incidence.
    pub irradiance: f64,
    /// The environment's constant radiance.
    pub env: f64,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Samples per pixel.
    pub spp: usize,
    /// Longest path (bounces) the renderers trace.
    pub max_depth: usize,
}

impl Lock {
    /// The preview's scene.
    pub fn preview() -> Lock {
        let s = RenderSettings::default();
        let segs = build_lock(&s.strand);
        let mut fibers: Vec<Vec<(V3, f64)>> = Vec::new();
        for seg in &segs {
            let f = seg.fiber as usize;
            if fibers.len() <= f {
                fibers.push(vec![(seg.a, seg.ra), (seg.a, seg.ra)]);
            }
            fibers[f].push((seg.b, seg.rb));
        }
        for f in &mut fibers {
            let last = *f.last().expect("a fiber has segments");
            f.push(last);
        }
        let c = s.camera;
        let (e, a) = (c.elev_deg.to_radians(), c.azim_deg.to_radians());
        let light = s.light.expect("the preview has a key light");
        let env = (0..3)
            .map(|i| 0.5 * (s.env.top[i] + s.env.bottom[i]))
            .sum::<f64>()
            / 3.0;
        Lock {
            fibers,
            eye: V3::new(a.sin() * e.cos(), e.sin(), a.cos() * e.cos()) * c.dist,
            fov_deg: c.fov_deg,
            light_dir: light.dir,
            irradiance: light.irradiance[1],
            env,
            width: s.width,
            height: s.height,
            spp: s.spp,
            max_depth: s.max_depth,
        }
    }
}

fn v3(v: V3, sep: &str) -> String {
    [v.x, v.y, v.z].map(|x| Num(x).to_string()).join(sep)
}

/// The control-point file beside a Mitsuba scene `out`: `<stem>.curves.txt`.
pub fn curves_path(out: &Path) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    out.with_file_name(format!("{stem}.curves.txt"))
}

/// Mitsuba 3 scene of `m` on `lock`: the scene XML (referring to `curves`, a file name
/// beside it) and the control-point file (`x y z radius` per line, a blank line between
/// fibers: Mitsuba's `bsplinecurve` format, which allows no comment).
pub fn mitsuba(m: &Material, lock: &Lock, curves: &str) -> Result<(Written, String)> {
    let material = super::mitsuba::write(m)?;
    let mut s = String::from("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
    s.push_str(&format!(
        "<!-- {MARKER} ({}) for Mitsuba 3: the preview's test lock -->\n",
        crate::TOOL_VERSION
    ));
    for line in m.header(&material.notes) {
        s.push_str(&format!("<!-- {} -->\n", comment_safe(&line)));
    }
    s.push_str(&format!(
        r#"<!-- render: mitsuba THIS_FILE (-D spp=N -D width=W -D height=H to change the defaults), or mitsuba.load_file + mitsuba.render; {n} fibers -->
<scene version="3.0.0">
    <default name="spp" value="{spp}"/>
    <default name="width" value="{w}"/>
    <default name="height" value="{h}"/>
    <integrator type="path">
        <integer name="max_depth" value="{depth}"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="{fov}"/>
        <string name="fov_axis" value="y"/>
        <transform name="to_world">
            <lookat origin="{eye}" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="$width"/>
            <integer name="height" value="$height"/>
            <rfilter type="box"/>
        </film>
    </sensor>
    <emitter type="directional">
        <vector name="direction" value="{dir}"/>
        <rgb name="irradiance" value="{irr}, {irr}, {irr}"/>
    </emitter>
    <emitter type="constant">
        <rgb name="radiance" value="{env}, {env}, {env}"/>
    </emitter>
"#,
        n = lock.fibers.len(),
        depth = lock.max_depth,
        fov = Num(lock.fov_deg),
        eye = v3(lock.eye, ", "),
        spp = lock.spp,
        w = lock.width,
        h = lock.height,
        dir = v3(lock.light_dir * -1.0, ", "),
        irr = Num(lock.irradiance),
        env = Num(lock.env),
    ));
    s.push_str(&super::mitsuba::bsdf_element(m, "", "    "));
    let id = identifier(&format!("furfit_{}", m.name));
    s.push_str(&format!(
        "    <shape type=\"bsplinecurve\">\n        <string name=\"filename\" value=\"{curves}\"/>\n        <ref id=\"{id}\"/>\n    </shape>\n</scene>\n"
    ));
    let mut c = String::new();
    for (i, f) in lock.fibers.iter().enumerate() {
        if i > 0 {
            c.push('\n');
        }
        for (p, r) in f {
            c.push_str(&format!("{} {}\n", v3(*p, " "), Num(*r)));
        }
    }
    Ok((
        Written {
            text: s,
            notes: material.notes,
        },
        c,
    ))
}

/// pbrt-v4 scene of `m` on `lock`, one file (`film` names the image it writes).
pub fn pbrt(m: &Material, lock: &Lock, film: &str) -> Result<Written> {
    let material = super::pbrt::write(m)?;
    let mut s = format!(
        "# {MARKER} ({}) for pbrt-v4: the preview's test lock\n",
        crate::TOOL_VERSION
    );
    for line in m.header(&material.notes) {
        s.push_str(&format!("# {line}\n"));
    }
    let light = lock.light_dir * 10.0;
    s.push_str(&format!(
        "# render: pbrt THIS_FILE; {n} fibers\n\
         # pbrt's camera space is left-handed: the x flip keeps the image as Mitsuba's and furfit render's\n\
         Scale -1 1 1\n\
         LookAt {eye}  0 0 0  0 1 0\n\
         Camera \"perspective\" \"float fov\" [ {fov} ]\n\
         Sampler \"zsobol\" \"integer pixelsamples\" [ {spp} ]\n\
         Integrator \"volpath\" \"integer maxdepth\" [ {depth} ]\n\
         Film \"rgb\" \"integer xresolution\" [ {w} ] \"integer yresolution\" [ {h} ] \"string filename\" [ \"{film}\" ]\n\
         WorldBegin\n\
         LightSource \"distant\" \"point3 from\" [ {from} ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ {irr} {irr} {irr} ]\n\
         LightSource \"infinite\" \"rgb L\" [ {env} {env} {env} ]\n\
         AttributeBegin\n",
        n = lock.fibers.len(),
        eye = v3(lock.eye, " "),
        fov = Num(lock.fov_deg),
        spp = lock.spp,
        depth = lock.max_depth,
        w = lock.width,
        h = lock.height,
        from = v3(light, " "),
        irr = Num(lock.irradiance),
        env = Num(lock.env),
    ));
    s.push_str(&super::pbrt::material_block(m));
    for f in &lock.fibers {
        if f.len() < 4 {
            return Err(Error::Invalid(
                "a fiber of fewer than 4 control points".into(),
            ));
        }
        let pts: Vec<String> = f.iter().map(|(p, _)| v3(*p, " ")).collect();
        s.push_str(&format!(
            "Shape \"curve\" \"string basis\" [ \"bspline\" ] \"string type\" [ \"cylinder\" ] \"point3 P\" [ {} ] \"float width0\" [ {} ] \"float width1\" [ {} ]\n",
            pts.join(" "),
            Num(2.0 * f[0].1),
            Num(2.0 * f[f.len() - 1].1)
        ));
    }
    s.push_str("AttributeEnd\n");
    Ok(Written {
        text: s,
        notes: material.notes,
    })
}
