//! Summary statistics over datasets: mean and 95 % interval (1.96·std/√n, population std), as
//! the thesis's plots show them; and, for comparing two settings dataset by dataset, the paired
//! difference with a Student-t interval (the sample std and t quantiles, since a search or a race
//! compares on as few as 2–10 datasets, where 1.96 would claim too much).

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

/// Mean of paired differences with a two-sided Student-t interval: `mean ± t·sd/√n`, `sd` the
/// sample standard deviation (divides by n − 1), `t` the quantile of Student's t with n − 1
/// degrees of freedom at (1 + confidence) / 2.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Paired {
    /// Number of pairs.
    pub n: usize,
    /// Mean difference.
    pub mean: f64,
    /// Sample standard deviation of the differences.
    pub sd: f64,
    /// Half-width of the interval.
    pub half: f64,
    /// Its confidence level (0.95).
    pub confidence: f64,
}

impl Paired {
    /// Lower end of the interval.
    pub fn low(&self) -> f64 {
        self.mean - self.half
    }
    /// Upper end of the interval.
    pub fn high(&self) -> f64 {
        self.mean + self.half
    }
    /// −1 when the interval lies below 0, +1 above it, 0 when it holds 0 (indistinguishable).
    pub fn sign(&self) -> i8 {
        if self.high() < 0.0 {
            -1
        } else if self.low() > 0.0 {
            1
        } else {
            0
        }
    }
    /// `mean ± half` with `digits` decimals.
    pub fn show(&self, digits: usize) -> String {
        format!("{:+.digits$} ± {:.digits$}", self.mean, self.half)
    }
}

/// The paired differences `a[i] − b[i]` over the datasets both scored, with a t interval at
/// `confidence`; `None` for fewer than 2 pairs or a non-finite difference (a diverged dataset on
/// one side only makes the difference ±∞, which no interval describes).
pub fn paired(a: &[Option<f64>], b: &[Option<f64>], confidence: f64) -> Option<Paired> {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| Some((*x)? - (*y)?)).collect::<Option<Vec<f64>>>()?;
    let n = d.len();
    if n < 2 || d.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let mean = d.iter().sum::<f64>() / n as f64;
    let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    let t = t_quantile((1.0 + confidence) / 2.0, (n - 1) as f64);
    Some(Paired { n, mean, sd, half: t * sd / (n as f64).sqrt(), confidence })
}

/// The `p` quantile (0.5 ≤ p < 1) of Student's t with `df` degrees of freedom, by bisection on
/// the distribution function to full double precision.
pub fn t_quantile(p: f64, df: f64) -> f64 {
    assert!((0.5..1.0).contains(&p) && df > 0.0, "t_quantile({p}, {df})");
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while t_cdf(hi, df) < p {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if t_cdf(mid, df) < p {
            lo = mid
        } else {
            hi = mid
        }
        if hi - lo <= f64::EPSILON * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Student's t distribution function at `t` ≥ 0: 1 − ½·I_x(df/2, ½) with x = df / (df + t²).
fn t_cdf(t: f64, df: f64) -> f64 {
    1.0 - 0.5 * incomplete_beta(df / (df + t * t), df / 2.0, 0.5)
}

/// The regularised incomplete beta function I_x(a, b), from its continued fraction (modified
/// Lentz), using the symmetry I_x(a, b) = 1 − I_{1−x}(b, a) where the fraction converges slowly.
fn incomplete_beta(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front = (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_fraction(x, a, b) / a
    } else {
        1.0 - front * beta_fraction(1.0 - x, b, a) / b
    }
}

fn beta_fraction(x: f64, a: f64, b: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let mut c = 1.0;
    let mut d = 1.0 - (a + b) * x / (a + 1.0);
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..=500 {
        let m = m as f64;
        // Even step, then odd step of the fraction.
        for num in [
            m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m)),
            -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0)),
        ] {
            d = 1.0 + num * d;
            if d.abs() < TINY {
                d = TINY;
            }
            c = 1.0 + num / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            h *= d * c;
        }
        if (d * c - 1.0).abs() < 1e-16 {
            break;
        }
    }
    h
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms: about 15 significant digits).
fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x)Γ(1 − x) = π / sin(πx).
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let s = G[1..].iter().enumerate().fold(G[0], |s, (i, g)| s + g / (x + i as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_match_the_tables() {
        // Two-sided 95 % critical values, df 1, 2, 4, 9, 19, 29, 100, and the normal limit.
        for (df, t) in [
            (1.0, 12.706_204_736),
            (2.0, 4.302_652_730),
            (4.0, 2.776_445_105),
            (9.0, 2.262_157_163),
            (19.0, 2.093_024_054),
            (29.0, 2.045_229_642),
            (100.0, 1.983_971_519),
            (1e7, 1.959_964_1),
        ] {
            let q = t_quantile(0.975, df);
            assert!((q - t).abs() < 1e-6, "df {df}: {q} vs {t}");
        }
        assert!((t_quantile(0.995, 9.0) - 3.249_835_542).abs() < 1e-6);
    }

    #[test]
    fn paired_differences_by_hand() {
        // Differences 1, 2, 3, 4, 5: mean 3, sample sd √2.5, t(0.975, 4) = 2.776445.
        let a = [Some(2.0), Some(4.0), Some(6.0), Some(8.0), Some(10.0)];
        let b = [Some(1.0), Some(2.0), Some(3.0), Some(4.0), Some(5.0)];
        let p = paired(&a, &b, 0.95).unwrap();
        assert_eq!((p.n, p.mean), (5, 3.0));
        assert!((p.sd - 2.5f64.sqrt()).abs() < 1e-15);
        assert!((p.half - 2.776_445_105 * 2.5f64.sqrt() / 5f64.sqrt()).abs() < 1e-8);
        assert_eq!(p.sign(), 1);
        assert_eq!(paired(&b, &a, 0.95).unwrap().sign(), -1);
        // A diverged dataset on one side, or a single pair, has no interval.
        assert!(paired(&[Some(1.0), None], &[Some(0.0), Some(0.0)], 0.95).is_none());
        assert!(paired(&[Some(1.0)], &[Some(0.0)], 0.95).is_none());
        // Noise around 0: indistinguishable.
        let c = [Some(1.0), Some(-1.0), Some(0.5), Some(-0.4)];
        assert_eq!(paired(&c, &[Some(0.0); 4], 0.95).unwrap().sign(), 0);
    }

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
