//! `gyrocomp evaluate` (placeholder, filled in below).
