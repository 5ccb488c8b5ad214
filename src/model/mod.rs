//! The 5-lobe fur fiber BCSDF (seed paper Sections 3-5).
