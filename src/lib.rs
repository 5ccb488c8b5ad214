//! furfit: fit, check and preview the 5-lobe fur fiber BCSDF of Yan et al. 2017
//! ("An Efficient and Practical Near and Far Field Fur Reflectance Model", the seed paper
//! `000_85b68d9b3972f7ab.txt`) with the conventions of the project's `MODEL.md`
//! (`../shared/spec/`).
//!
//! The pipeline, module by module (see `ARCHITECTURE.md`):
//! [`params`] -> [`profile`] (load) -> [`model`] (near / far / multi-scale BCSDF) ->
//! [`fit`] -> [`report`]; [`simulate`] is the independent virtual goniometer that makes
//! `measurements/`; [`render`] previews fitted fur. The binary's [`cli`] only parses
//! arguments and prints.
//!
//! The crate is an application's library: its API docs are read with
//! `cargo doc --document-private-items`, so public items may link to private ones.
#![allow(rustdoc::private_intra_doc_links)]
#![warn(missing_docs)]

pub mod cancel;
pub mod cli;
pub mod error;
pub mod export;
pub mod fit;
pub mod grid;
pub mod io;
pub mod model;
pub mod models;
pub mod params;
pub mod profile;
pub mod render;
pub mod report;
pub mod simulate;
pub mod synth;
pub mod text;
pub mod timing;
pub mod view;

pub use error::{Error, Result};

/// The tool and the git revision it was built from (`build.rs`), as fit files, reports and
/// simulated profiles record it.
pub const TOOL_VERSION: &str = concat!(
    "furfit ",
    env!("CARGO_PKG_VERSION"),
    " (git ",
    env!("FURFIT_GIT_REV"),
    ")"
);
pub use params::{FurParams, ParamId};
pub use profile::{Profile, Sample};
