//! Summary statistics over datasets: mean and 95 % interval (1.96·std/√n, population std), as
//! the thesis's plots show them.

use serde::{Deserialize, Serialize};

/// Mean, population standard deviation and 95 % half-interval of a sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Number of values.
    pub n: usize,
    /// Arithmetic mean.
    pub mean: f64,
    /// Population standard deviation (divides by n).
    pub std: f64,
    /// Half-width of the 95 % interval: 1.96·std/√n.
    pub ci95: f64,
}

/// Summarises `values`; `None` when empty.
pub fn summarize(values: &[f64]) -> Option<Summary> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
    let std = var.sqrt();
    Some(Summary { n, mean, std, ci95: 1.96 * std / (n as f64).sqrt() })
}

/// `mean ± ci95` with `digits` decimals, or `−∞ (diverged)` when there is no summary (a dataset
/// diverged).
pub fn interval(s: Option<Summary>, digits: usize) -> String {
    s.map_or("−∞ (diverged)".into(), |v| format!("{:.digits$} ± {:.digits$}", v.mean, v.ci95))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_inputs() {
        // Values 2, 4, 4, 4, 5, 5, 7, 9: mean 5, population std 2.
        let s = summarize(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]).unwrap();
        assert_eq!(s.mean, 5.0);
        assert_eq!(s.std, 2.0);
        assert!((s.ci95 - 1.96 * 2.0 / 8f64.sqrt()).abs() < 1e-15);
        let one = summarize(&[3.0]).unwrap();
        assert_eq!((one.mean, one.std, one.ci95), (3.0, 0.0, 0.0));
        assert!(summarize(&[]).is_none());
    }
}
