//! Shared plotting helpers (filled in below).
