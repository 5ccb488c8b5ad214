//! The registered models ([`MODELS`]) and their look-up by name: the one list a new model
//! joins (ARCHITECTURE.md "Where to add").

use super::interface::FiberModel;
use super::{chiang2016, marschner2003, yan2017};

/// The registered models, default first.
pub static MODELS: [&'static dyn FiberModel; 3] = [
    &yan2017::Yan2017,
    &marschner2003::Marschner2003,
    &chiang2016::Chiang2016,
];

/// The default model (`yan2017`).
pub fn default_model() -> &'static dyn FiberModel {
    MODELS[0]
}

/// The names of the registered models, for messages.
pub fn names() -> Vec<&'static str> {
    MODELS.iter().map(|m| m.name()).collect()
}

/// A registered model by name (case-insensitive).
pub fn by_name(name: &str) -> crate::Result<&'static dyn FiberModel> {
    let key = name.trim().to_ascii_lowercase();
    MODELS
        .iter()
        .copied()
        .find(|m| m.name() == key)
        .ok_or_else(|| {
            crate::Error::Invalid(format!(
                "unknown model '{}' (expected one of: {})",
                name.trim(),
                names().join(", ")
            ))
        })
}
