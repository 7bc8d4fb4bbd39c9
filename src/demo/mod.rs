//! The built-in demo scene: analytic objects rendered by a CPU ray tracer, with exact truth.
