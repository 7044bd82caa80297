//! Shared helpers for the fixture-based tests and benchmarks of incise: mesh generators for
//! tests and the `faer` oracle. Not part of the product.
