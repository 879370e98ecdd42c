//! Simulated plant (host only).
