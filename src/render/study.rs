//! Convergence and culling studies (filled in below).
