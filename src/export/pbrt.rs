//! pbrt-v4's `hair` material (`src/pbrt/materials.cpp` `HairMaterial::Create`, the BSDF
//! `HairBxDF` of `src/pbrt/bxdfs.{h,cpp}`), written as a `Material "hair"` block.
//!
//! `chiang2016` *is* pbrt-v4's `HairBxDF` (MODEL.md, [`crate::models::chiang2016`]), so
//! every parameter maps to itself:
//!
//! | chiang2016 | pbrt-v4 | why |
//! |---|---|---|
//! | `eta` | `"float eta"` | `HairBxDF(h, eta, ...)`, relative to the outside (1) |
//! | `beta_m`, `beta_n` | `"float beta_m"`, `"float beta_n"` | the same roughness maps (`HairBxDF::HairBxDF`); pbrt `CHECK`s both in [0, 1] |
//! | `alpha` (deg) | `"float alpha"` (deg) | `sin2kAlpha[0] = sin(Radians(alpha))`, tilting `wo` (the camera) |
//! | `sigma_a` | `"rgb sigma_a"` | `SpectrumType::Unbounded`; `T = Exp(-sigma_a * (2 cosGamma_t / cosTheta_t))`: per unit radius |
//!
//! pbrt renders spectrally: an `"rgb"` absorption becomes an `RGBUnboundedSpectrum`,
//! exactly constant for a grey one (equal r, g, b), a smooth spectrum whose r, g, b match
//! the values otherwise.

use super::material::{Material, Written, MARKER};
use crate::error::{Num, Result};

/// The scene-file block of `m`.
pub fn write(m: &Material) -> Result<Written> {
    let notes = Vec::new();
    let mut s = format!("# {MARKER} ({}) for pbrt-v4\n", crate::TOOL_VERSION);
    for line in m.header(&notes) {
        s.push_str(&format!("# {line}\n"));
    }
    s.push_str(&material_block(m));
    Ok(Written { text: s, notes })
}

/// `Material "hair"` with its parameters, one per line.
pub fn material_block(m: &Material) -> String {
    let f = |name: &str, v: f64| format!("    \"float {name}\" [ {} ]\n", Num(v));
    let mut s = String::from("Material \"hair\"\n");
    s.push_str(&format!(
        "    \"rgb sigma_a\" [ {} ]\n",
        m.sigma_a.map(|v| Num(v).to_string()).join(" ")
    ));
    s.push_str(&f("eta", m.eta));
    s.push_str(&f("beta_m", m.beta_m));
    s.push_str(&f("beta_n", m.beta_n));
    s.push_str(&f("alpha", m.alpha_deg));
    s
}

/// A pbrt-v4 parameter list read back: `(type, name, values)` of each `"type name" [ ... ]`
/// after the directive `directive` (comments and the other directives skipped). For the
/// tests and for checking an export: pbrt has no package to parse it with.
pub fn parse_params(text: &str, directive: &str) -> Option<Vec<(String, String, Vec<String>)>> {
    let tokens = tokenize(text);
    let start = tokens.iter().position(|t| t == directive)?;
    let mut out = Vec::new();
    let mut i = start + 2; // the directive and its quoted name
    while i < tokens.len() {
        let t = &tokens[i];
        let Some(decl) = t.strip_prefix('"').and_then(|x| x.strip_suffix('"')) else {
            break;
        };
        let mut parts = decl.split_whitespace();
        let (Some(ty), Some(name), None) = (parts.next(), parts.next(), parts.next()) else {
            break;
        };
        let mut vals = Vec::new();
        i += 1;
        if tokens.get(i).map(String::as_str) == Some("[") {
            i += 1;
            while i < tokens.len() && tokens[i] != "]" {
                vals.push(tokens[i].clone());
                i += 1;
            }
            i += 1;
        } else if let Some(v) = tokens.get(i) {
            vals.push(v.clone());
            i += 1;
        }
        out.push((ty.to_string(), name.to_string(), vals));
    }
    Some(out)
}

/// pbrt's tokens: quoted strings (with their quotes), brackets, bare words; `#` comments
/// to the end of the line.
fn tokenize(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines() {
        let mut chars = line.chars().peekable();
        while let Some(&c) = chars.peek() {
            match c {
                '#' => break,
                '"' => {
                    chars.next();
                    let mut s = String::from("\"");
                    for d in chars.by_ref() {
                        s.push(d);
                        if d == '"' {
                            break;
                        }
                    }
                    out.push(s);
                }
                '[' | ']' => {
                    out.push(c.to_string());
                    chars.next();
                }
                c if c.is_whitespace() => {
                    chars.next();
                }
                _ => {
                    let mut s = String::new();
                    while let Some(&d) = chars.peek() {
                        if d.is_whitespace() || d == '[' || d == ']' || d == '"' || d == '#' {
                            break;
                        }
                        s.push(d);
                        chars.next();
                    }
                    out.push(s);
                }
            }
        }
    }
    out
}
