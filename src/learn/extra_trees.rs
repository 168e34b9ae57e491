//! Extra-Trees regression (SPEC §3), written in its own change.
