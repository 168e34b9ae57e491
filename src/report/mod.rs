//! Reports: statistics over datasets, tables, plots and markdown.

pub mod baseline;
pub mod batch;
pub mod claims;
pub mod comparison;
pub mod plot;
pub mod policy;
pub mod rollout;
pub mod search;
pub mod validation;
