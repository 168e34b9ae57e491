//! The CPU's instruction sets, detected once for both learners' kernels, and the one override.
//!
//! The Extra-Trees and the MLP each have kernels compiled for several levels ([`Isa`]) that give
//! the same bits and differ only in speed. Each learner runs at the best level whose features this
//! CPU has, capped by the environment variable `BFQI_ISA` when it is set: `avx512`, `avx2` or
//! `portable` (any other value caps nothing). `BFQI_MLP_ISA`, its former name, is read when
//! `BFQI_ISA` is not set. The cap is how the slower paths are benchmarked and how the test suite is
//! run on each of them (`BFQI_ISA=portable cargo test --release`). On aarch64 the MLP runs at
//! `neon` (every aarch64 CPU has it; `BFQI_ISA=portable` caps it), the Extra-Trees at `portable`
//! (compiled for the aarch64 baseline, where the compiler vectorises with NEON).
//!
//! A level needs different features for each learner, as each compiles its kernels with its own:
//!
//! | level | Extra-Trees | MLP |
//! |---|---|---|
//! | `avx512` | avx512f, avx512vl, avx512bw, avx512dq, popcnt | avx512f, avx512vl, avx2, fma |
//! | `avx2` | avx2 | avx2, fma |
//! | `neon` | — (runs `portable`) | aarch64 baseline |
//! | `portable` | — | — |

use std::sync::OnceLock;

/// The variable that caps both learners' level.
const OVERRIDE: &str = "BFQI_ISA";
/// `OVERRIDE`'s former name, when only the MLP read it (scripts may still set it).
const OVERRIDE_ALIAS: &str = "BFQI_MLP_ISA";

/// An instruction-set level kernels are compiled for, in increasing order of speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Isa {
    /// Plain loops: baseline x86-64 (where the MLP's `mul_add` calls the C library's exact but
    /// slow `fmaf`, so it is a last resort), or any other target (e.g. aarch64, with native FMA).
    Portable,
    /// NEON on aarch64 (part of its baseline, with fused multiply-adds): 4 lanes per instruction.
    Neon,
    /// AVX2 (with FMA for the MLP): 8 lanes per instruction.
    Avx2,
    /// AVX-512 (AVX-512F with FMA for the MLP): 16 lanes per instruction.
    Avx512,
}

/// What is detected, once per process.
struct Detected {
    /// This CPU's features (all false off x86-64).
    avx512f: bool,
    avx512vl: bool,
    avx512bw: bool,
    avx512dq: bool,
    popcnt: bool,
    avx2: bool,
    fma: bool,
    /// The level each learner runs at.
    extra_trees: Isa,
    mlp: Isa,
}

fn detected() -> &'static Detected {
    static DETECTED: OnceLock<Detected> = OnceLock::new();
    DETECTED.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        use std::arch::is_x86_feature_detected as has;
        #[cfg(not(target_arch = "x86_64"))]
        macro_rules! has {
            ($f:tt) => {
                false
            };
        }
        let mut d = Detected {
            avx512f: has!("avx512f"),
            avx512vl: has!("avx512vl"),
            avx512bw: has!("avx512bw"),
            avx512dq: has!("avx512dq"),
            popcnt: has!("popcnt"),
            avx2: has!("avx2"),
            fma: has!("fma"),
            extra_trees: Isa::Portable,
            mlp: Isa::Portable,
        };
        let cap = cap(std::env::var(OVERRIDE).or_else(|_| std::env::var(OVERRIDE_ALIAS)).ok().as_deref());
        let best = |runs: fn(&Detected, Isa) -> bool| {
            Isa::ALL.into_iter().find(|&i| i <= cap && runs(&d, i)).unwrap_or(Isa::Portable)
        };
        (d.extra_trees, d.mlp) = (best(Detected::runs_extra_trees), best(Detected::runs_mlp));
        d
    })
}

/// The level an override value caps at (none, i.e. the best, for anything but a level's name).
fn cap(value: Option<&str>) -> Isa {
    match value {
        Some("portable") => Isa::Portable,
        Some("neon") => Isa::Neon,
        Some("avx2") => Isa::Avx2,
        _ => Isa::Avx512,
    }
}

impl Detected {
    fn runs_extra_trees(&self, isa: Isa) -> bool {
        match isa {
            Isa::Avx512 => self.avx512f && self.avx512vl && self.avx512bw && self.avx512dq && self.popcnt,
            Isa::Avx2 => self.avx2,
            Isa::Neon => false,
            Isa::Portable => true,
        }
    }

    fn runs_mlp(&self, isa: Isa) -> bool {
        match isa {
            Isa::Avx512 => self.avx512f && self.avx512vl && self.avx2 && self.fma,
            Isa::Avx2 => self.avx2 && self.fma,
            Isa::Neon => cfg!(target_arch = "aarch64"),
            Isa::Portable => true,
        }
    }
}

impl Isa {
    /// Every level, best first.
    pub(crate) const ALL: [Isa; 4] = [Isa::Avx512, Isa::Avx2, Isa::Neon, Isa::Portable];

    /// Whether this CPU has every feature the Extra-Trees kernels of this level are compiled with
    /// (whatever the cap). Only the x86-64 builds ask: elsewhere the trees have one build.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub(crate) fn runs_extra_trees(self) -> bool {
        detected().runs_extra_trees(self)
    }

    /// Whether this CPU has every feature the MLP kernels of this level are compiled with
    /// (whatever the cap).
    pub(crate) fn runs_mlp(self) -> bool {
        detected().runs_mlp(self)
    }

    /// Name for reports, as `BFQI_ISA` spells it.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Isa::Avx512 => "avx512",
            Isa::Avx2 => "avx2",
            Isa::Neon => "neon",
            Isa::Portable => "portable",
        }
    }
}

/// The level the Extra-Trees kernels run at: the best this CPU supports, capped by `BFQI_ISA`.
pub(crate) fn extra_trees() -> Isa {
    detected().extra_trees
}

/// The level the MLP kernels run at: the best this CPU supports, capped by `BFQI_ISA`.
pub(crate) fn mlp() -> Isa {
    #[cfg(test)]
    if let Some(isa) = TEST_MLP_LEVEL.with(std::cell::Cell::get) {
        return isa;
    }
    detected().mlp
}

#[cfg(test)]
thread_local! {
    /// The MLP level tests force on this thread (`BFQI_ISA` is read once per process).
    static TEST_MLP_LEVEL: std::cell::Cell<Option<Isa>> = const { std::cell::Cell::new(None) };
}

/// Runs `f` with the MLP kernels of `isa` on this thread (whole pipelines at each level, in tests:
/// run it on a one-thread pool so nested parallel work stays on this thread). The kernels'
/// dispatch still checks the CPU, so a level it lacks cannot run.
#[cfg(test)]
pub(crate) fn with_mlp_level<R>(isa: Isa, f: impl FnOnce() -> R) -> R {
    assert!(isa.runs_mlp(), "{isa:?} does not run on this CPU");
    let before = TEST_MLP_LEVEL.with(|c| c.replace(Some(isa)));
    let out = f();
    TEST_MLP_LEVEL.with(|c| c.set(before));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_override_caps_and_anything_else_does_not() {
        assert_eq!(cap(Some("portable")), Isa::Portable);
        assert_eq!(cap(Some("avx2")), Isa::Avx2);
        assert_eq!(cap(Some("neon")), Isa::Neon);
        assert_eq!(cap(Some("avx512")), Isa::Avx512);
        assert_eq!(cap(Some("AVX2")), Isa::Avx512);
        assert_eq!(cap(None), Isa::Avx512);
    }

    #[test]
    fn each_learner_runs_a_level_this_cpu_has() {
        assert!(extra_trees().runs_extra_trees() && mlp().runs_mlp());
        assert!(Isa::Portable.runs_extra_trees() && Isa::Portable.runs_mlp());
        // Nothing above the chosen level is skipped unless the override capped it.
        let cap = cap(std::env::var(OVERRIDE).or_else(|_| std::env::var(OVERRIDE_ALIAS)).ok().as_deref());
        for isa in Isa::ALL.into_iter().filter(|&i| i <= cap) {
            assert!(!isa.runs_extra_trees() || isa <= extra_trees(), "{isa:?}");
            assert!(!isa.runs_mlp() || isa <= mlp(), "{isa:?}");
        }
    }
}
