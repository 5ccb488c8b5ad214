//! Mitsuba 3's `hair` BSDF (`src/bsdfs/hair.cpp`, Mitsuba 3.5-3.9), written as a
//! `<bsdf type="hair">` XML document.
//!
//! | chiang2016 | Mitsuba 3 | why |
//! |---|---|---|
//! | `beta_m` | `longitudinal_roughness` | `update()`: `m_v[0] = (0.726 b + 0.812 b^2 + 3.7 b^20)^2`, `v/4`, `4v`, `4v` as pbrt-v4 |
//! | `beta_n` | `azimuthal_roughness` | `m_s = sqrt(pi/8) (0.265 b + 1.194 b^2 + 5.372 b^22)` |
//! | `alpha` (deg) | `scale_tilt` (deg) | `reframe_with_scales` tilts `si.wi` (the camera) by `-2a`, `+a`, `+4a`: pbrt's sign |
//! | `eta` | `int_ior` = `eta`, `ext_ior` = 1 | `m_eta = int_ior / ext_ior`; the default `ext_ior` is air (1.000277), which would change `eta` |
//! | `sigma_a` | `<rgb name="sigma_a">` | `transmittance = exp(-sigma_a * 2 cos(gamma_t) / cos(theta_t))`: per unit radius (the docs' "inverse scene units" aside), `scale` left at 1 |
//!
//! Mitsuba's frame: tangent `y` (toward the tip), azimuth `atan2(z, x)`, `h` read from
//! `si.wi`, which is the camera side; `eval` returns `sum_p M_p A_p N_p` (its
//! `longitudinal_scattering * 2 pi` is d'Eon's `M_p`). Mitsuba stores the parameters in
//! single precision and refuses `int_ior == ext_ior`: an `eta` that rounds to 1 in `f32`
//! is refused here.

use super::material::{comment_safe, identifier, Material, Written, MARKER};
use crate::error::{Error, Num, Result};

/// The XML document of `m`.
pub fn write(m: &Material) -> Result<Written> {
    if m.eta as f32 <= 1.0 {
        return Err(Error::Param {
            key: "eta".into(),
            msg: format!(
                "{} rounds to 1 in Mitsuba's single precision, and Mitsuba's hair refuses int_ior == ext_ior",
                Num(m.eta)
            ),
        });
    }
    let notes = Vec::new();
    let mut s = String::from("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
    s.push_str(&format!(
        "<!-- {MARKER} ({}) for Mitsuba 3 -->\n",
        crate::TOOL_VERSION
    ));
    for line in m.header(&notes) {
        s.push_str(&format!("<!-- {} -->\n", comment_safe(&line)));
    }
    s.push_str(&bsdf_element(m, "version=\"3.0.0\" ", ""));
    Ok(Written { text: s, notes })
}

/// The `<bsdf type="hair">` element (with `attrs` in its opening tag, each line after the
/// first prefixed by `indent`), as the document and a scene embed it.
pub fn bsdf_element(m: &Material, attrs: &str, indent: &str) -> String {
    let id = identifier(&format!("furfit_{}", m.name));
    let mut s = format!("{indent}<bsdf {attrs}type=\"hair\" id=\"{id}\">\n");
    let float = |name: &str, v: f64| {
        format!(
            "{indent}    <float name=\"{name}\" value=\"{}\"/>\n",
            Num(v)
        )
    };
    s.push_str(&float("longitudinal_roughness", m.beta_m));
    s.push_str(&float("azimuthal_roughness", m.beta_n));
    s.push_str(&float("scale_tilt", m.alpha_deg));
    s.push_str(&float("int_ior", m.eta));
    s.push_str(&float("ext_ior", 1.0));
    s.push_str(&format!(
        "{indent}    <rgb name=\"sigma_a\" value=\"{}\"/>\n",
        m.sigma_a.map(|v| Num(v).to_string()).join(", ")
    ));
    s.push_str(&format!("{indent}</bsdf>\n"));
    s
}
