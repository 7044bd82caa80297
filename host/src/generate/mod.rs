//! The synthetic-scene generator (being written).
