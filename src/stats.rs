//! Summary statistics over datasets: mean and 95 % interval (1.96·std/√n, population std), as
//! the thesis's plots show them; and, for comparing two settings dataset by dataset, the paired
//! difference with a Student-t interval (the sample std and t quantiles, since a search or a race
//! compares on as few as 2–10 datasets, where 1.96 would claim too much); and one-sided paired
//! tests (Wilcoxon signed-rank, t) with p-values, for racing settings inside a search.

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

/// A one-sided paired test that says whether one setting scores lower than another on the same
/// datasets (`search.race.test`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PairedTest {
    /// Wilcoxon's signed-rank test: ranks, so one outlying dataset cannot decide alone.
    Wilcoxon,
    /// Student's paired t test on the differences.
    T,
}

impl PairedTest {
    /// `wilcoxon` or `t`, as spec files spell it.
    pub fn name(&self) -> &'static str {
        match self {
            PairedTest::Wilcoxon => "wilcoxon",
            PairedTest::T => "t",
        }
    }

    /// The one-sided p-value of "the differences `d` (a − b per dataset) lie below 0".
    pub fn p_less(&self, d: &[f64]) -> f64 {
        match self {
            PairedTest::Wilcoxon => wilcoxon_less(d),
            PairedTest::T => t_less(d),
        }
    }

    /// The fewest datasets at which this test can give a p-value below `alpha` (every difference
    /// negative): a signed-rank test's smallest p-value on n pairs is 2⁻ⁿ, a t test's is 0 from 2
    /// pairs on.
    pub fn fewest(&self, alpha: f64) -> usize {
        match self {
            PairedTest::Wilcoxon => (1..64).find(|&n| 0.5f64.powi(n as i32) < alpha).unwrap_or(64),
            PairedTest::T => 2,
        }
    }
}

/// One-sided p-value of Wilcoxon's signed-rank test that the differences `d` lie below 0 (scipy's
/// `wilcoxon(d, alternative="less")`): zero differences are dropped (`zero_method="wilcox"`), tied
/// |d| share their mean rank, and the statistic is R⁺, the rank sum of the positive differences.
/// With at most 50 non-zero differences the p-value is exact: P(R⁺ ≤ r) counted over the 2ⁿ sign
/// patterns of the ranks as they are (mid-ranks included, the permutation distribution given the
/// ties). Without ties that is scipy's exact p-value; with ties scipy switches to the normal
/// approximation, which on 4 tied pairs can claim p = 0.03 where no sign pattern is rarer than
/// 2⁻⁴ — a race would stop a setting sooner than the test allows. Above 50, the normal
/// approximation with the tie correction of the variance (no continuity correction), as scipy's.
/// No non-zero difference: 1 (no evidence either way).
pub fn wilcoxon_less(d: &[f64]) -> f64 {
    let mut nz: Vec<f64> = d.iter().copied().filter(|x| *x != 0.0).collect();
    let n = nz.len();
    if n == 0 {
        return 1.0;
    }
    nz.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    // Twice the mean ranks over runs of equal |d| (integers: i + 1 + j over a run i..j), and the
    // tie term Σ(t³ − t).
    let (mut ranks2, mut r2_plus, mut ties, mut i) = (Vec::with_capacity(n), 0usize, 0.0, 0);
    while i < n {
        let j = (i..n).find(|&j| nz[j].abs() != nz[i].abs()).unwrap_or(n);
        let rank2 = i + 1 + j;
        ranks2.extend(std::iter::repeat_n(rank2, j - i));
        r2_plus += nz[i..j].iter().filter(|x| **x > 0.0).count() * rank2;
        let t = (j - i) as f64;
        ties += t * t * t - t;
        i = j;
    }
    if n <= 50 {
        // counts[s]: sign patterns whose positive doubled ranks sum to s (exact in f64 to 2⁵³).
        let max = n * (n + 1);
        let mut counts = vec![0.0f64; max + 1];
        counts[0] = 1.0;
        for &k in &ranks2 {
            for s in (k..=max).rev() {
                counts[s] += counts[s - k];
            }
        }
        return counts[..=r2_plus].iter().sum::<f64>() / 2f64.powi(n as i32);
    }
    let r_plus = r2_plus as f64 / 2.0;
    let nf = n as f64;
    let mean = nf * (nf + 1.0) / 4.0;
    let var = nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0 - ties / 48.0;
    if var <= 0.0 {
        return 1.0;
    }
    normal_cdf((r_plus - mean) / var.sqrt())
}

/// One-sided p-value of the paired t test that the differences `d` lie below 0 (scipy's
/// `ttest_1samp(d, 0, alternative="less")`): P(T ≤ mean / (sd/√n)) with n − 1 degrees of freedom.
/// Fewer than 2 differences: 1. Differences all equal (sd 0): 0 when they are negative, else 1.
pub fn t_less(d: &[f64]) -> f64 {
    let n = d.len();
    if n < 2 {
        return 1.0;
    }
    let mean = d.iter().sum::<f64>() / n as f64;
    let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    if sd == 0.0 {
        return if mean < 0.0 { 0.0 } else { 1.0 };
    }
    let t = mean / (sd / (n as f64).sqrt());
    let df = (n - 1) as f64;
    let tail = 0.5 * incomplete_beta(df / (df + t * t), df / 2.0, 0.5);
    if t < 0.0 { tail } else { 1.0 - tail }
}

/// The standard normal distribution function: ½·erfc(−z/√2), erfc(x) = Q(½, x²) for x ≥ 0.
pub fn normal_cdf(z: f64) -> f64 {
    let x = z / std::f64::consts::SQRT_2;
    let erfc_abs = upper_gamma(0.5, x * x);
    if z < 0.0 { 0.5 * erfc_abs } else { 1.0 - 0.5 * erfc_abs }
}

/// The regularised upper incomplete gamma function Q(a, x): by its series below a + 1, by its
/// continued fraction (modified Lentz) above, where each converges fast.
fn upper_gamma(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let front = (a * x.ln() - x - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut k) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            k += 1.0;
            term *= x / k;
            sum += term;
            if term.abs() < sum.abs() * 1e-17 {
                break;
            }
        }
        return 1.0 - front * sum;
    }
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..1000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        d = lentz_floor(d);
        c = b + an / c;
        c = lentz_floor(c);
        d = 1.0 / d;
        h *= d * c;
        if (d * c - 1.0).abs() < 1e-16 {
            break;
        }
    }
    front * h
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

/// What modified Lentz's rule puts in place of a zero denominator of a continued fraction.
const TINY: f64 = 1e-300;

/// A denominator of a continued fraction kept away from zero (modified Lentz's rule).
fn lentz_floor(x: f64) -> f64 {
    if x.abs() < TINY { TINY } else { x }
}

fn beta_fraction(x: f64, a: f64, b: f64) -> f64 {
    let mut c = 1.0;
    let mut d = 1.0 - (a + b) * x / (a + 1.0);
    d = lentz_floor(d);
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
            d = lentz_floor(d);
            c = 1.0 + num / c;
            c = lentz_floor(c);
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

    #[test]
    fn normal_cdf_matches_the_tables() {
        for (z, p) in [
            (0.0, 0.5),
            (1.0, 0.841_344_746_068_543),
            (-1.0, 0.158_655_253_931_457),
            (1.959_963_984_540_054, 0.975),
            (-3.0, 0.001_349_898_031_630_1),
            (0.3, 0.617_911_422_188_953),
            (-6.0, 9.865_876_450_377e-10),
        ] {
            let q = normal_cdf(z);
            assert!((q - p).abs() < 1e-13 * p.max(1e-3), "Φ({z}) = {q}, tables {p}");
        }
    }

    #[test]
    fn wilcoxon_exact_p_values_by_hand() {
        // n = 5, every difference negative: R⁺ = 0, one pattern of 32.
        assert_eq!(wilcoxon_less(&[-1.0, -2.0, -3.0, -4.0, -5.0]), 1.0 / 32.0);
        // n = 6, R⁺ = 2 (the difference of rank 2 positive): sign patterns with R⁺ ≤ 2 are {},
        // {1}, {2}: 3 of 64.
        assert_eq!(wilcoxon_less(&[-0.1, 0.2, -0.3, -0.4, -0.5, -0.6]), 3.0 / 64.0);
        // n = 4, R⁺ = 5 (ranks 1 and 4): subsets of {1,2,3,4} summing to ≤ 5 are {}, 1, 2, 3, 4,
        // 12, 13, 14, 23: 9 of 16.
        assert_eq!(wilcoxon_less(&[4.0, -1.5, -2.5, 1.0]), 9.0 / 16.0);
        // Every difference positive: R⁺ = 15 of at most 15, p = 1.
        assert_eq!(wilcoxon_less(&[1.0, 2.0, 3.0, 4.0, 5.0]), 1.0);
        // Zeros are dropped: the n = 5 case again.
        assert_eq!(wilcoxon_less(&[0.0, -1.0, -2.0, 0.0, -3.0, -4.0, -5.0]), 1.0 / 32.0);
        assert_eq!(wilcoxon_less(&[0.0, 0.0]), 1.0);
        assert_eq!(wilcoxon_less(&[]), 1.0);
        // The fewest pairs that can reach p < 0.05: 2⁻⁵ = 0.031 (2⁻⁴ = 0.0625 cannot).
        assert_eq!(PairedTest::Wilcoxon.fewest(0.05), 5);
        assert_eq!(PairedTest::Wilcoxon.fewest(0.01), 7);
        assert_eq!(PairedTest::T.fewest(0.05), 2);
    }

    #[test]
    fn wilcoxon_with_ties_counts_sign_patterns_of_the_mid_ranks() {
        // |d| = 1, 1, 2, 3, 3, 3: mid-ranks 1.5, 1.5, 3, 5, 5, 5; positive: one 1.5 and one 5, so
        // R⁺ = 6.5. Of the 64 sign patterns, 17 have R⁺ ≤ 6.5 (listed by brute force).
        assert_eq!(wilcoxon_less(&[1.0, -1.0, -2.0, 3.0, -3.0, -3.0]), 17.0 / 64.0);
        // Four tied differences, all negative: 2⁻⁴, not the normal approximation's 0.029.
        assert_eq!(wilcoxon_less(&[-90.0, -90.0, -85.0, -90.0]), 1.0 / 16.0);
        assert_eq!(wilcoxon_less(&[40.0, 42.0, 38.0, 41.0, 39.0, 40.0]), 1.0);
    }

    #[test]
    fn wilcoxon_above_50_pairs_uses_the_tie_corrected_normal_approximation() {
        // 60 distinct differences, all negative: R⁺ = 0, z = −mean/√var.
        let many: Vec<f64> = (1..=60).map(|i| -(i as f64)).collect();
        let (m, v) = (60.0 * 61.0 / 4.0, 60.0 * 61.0 * 121.0 / 24.0);
        assert!((wilcoxon_less(&many) - normal_cdf(-m / f64::sqrt(v))).abs() < 1e-20);
        // 30 tied pairs: the variance loses 30·(2³ − 2)/48; z = −6.736551…, Φ(z) = 8.1095025e-12.
        let pairs: Vec<f64> = (0..60).map(|i| -((i / 2 + 1) as f64)).collect();
        let p = wilcoxon_less(&pairs);
        assert!((p - 8.109_502_507_979e-12).abs() < 1e-21, "{p}");
    }

    #[test]
    fn t_test_p_values() {
        // Differences −1, −2, −3, −4, −5: t = −3/(√2.5/√5) = −4.242641, df 4, where Student's
        // distribution function is ½ + ¾x − ¼x³ with x = t/√(4 + t²): p = 0.0066177997818.
        let p = t_less(&[-1.0, -2.0, -3.0, -4.0, -5.0]);
        assert!((p - 0.006_617_799_781_841).abs() < 1e-12, "{p}");
        // At the 0.975 quantile exactly, the p-value is 0.025.
        let q = t_quantile(0.975, 9.0);
        let d: Vec<f64> = (0..10).map(|i| if i % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let sd = (10.0f64 / 9.0).sqrt();
        let shifted: Vec<f64> = d.iter().map(|x| x - q * sd / 10f64.sqrt()).collect();
        assert!((t_less(&shifted) - 0.025).abs() < 1e-9, "{}", t_less(&shifted));
        assert!((t_less(&d) - 0.5).abs() < 1e-12);
        assert_eq!(t_less(&[-1.0, -1.0, -1.0]), 0.0);
        assert_eq!(t_less(&[2.0, 2.0]), 1.0);
        assert_eq!(t_less(&[-1.0]), 1.0);
        assert_eq!(PairedTest::T.p_less(&[-1.0, -1.0]), 0.0);
    }
}
