//! The early-stopped MLP (SPEC §3), written in its own change.
