//! The machine an invocation ran on, recorded beside the wall times it produced.
//!
//! A unit's numbers are the same on every CPU (the kernels give the same bits at every
//! instruction-set level), but its seconds are not: the same units ran 6–10× longer on an AVX2-only
//! VM than on an AVX-512 one. So every invocation that adds wall time to a run records where it
//! ran, and reports say it beside the times.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// Where an invocation ran: enough to tell two machines' wall times apart.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Machine {
    /// The CPU's model name (Linux's `/proc/cpuinfo`), or the architecture where none is readable.
    pub cpu: String,
    /// Logical CPUs the operating system offers this process.
    pub cpus: usize,
    /// Threads the invocation ran its work on (`--jobs`).
    pub threads: usize,
    /// The instruction-set level the MLP kernels ran at (`avx512`, `avx2`, `portable`).
    pub mlp_isa: String,
    /// The instruction-set level the Extra-Trees kernels ran at.
    pub extra_trees_isa: String,
}

impl Machine {
    /// This machine, with the threads of this process's work pool.
    pub fn this() -> Machine {
        Machine {
            cpu: cpu_model(std::fs::read_to_string("/proc/cpuinfo").ok().as_deref())
                .unwrap_or_else(|| std::env::consts::ARCH.to_string()),
            cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
            threads: rayon::current_num_threads(),
            mlp_isa: crate::learn::cpu::mlp().name().into(),
            extra_trees_isa: crate::learn::cpu::extra_trees().name().into(),
        }
    }

    /// A short label for reports: `AMD EPYC, avx2, 2 threads`. The MLP's level is the one named:
    /// its kernels are where a search spends its time.
    pub fn label(&self) -> String {
        let threads = if self.threads == 1 { "1 thread".to_string() } else { format!("{} threads", self.threads) };
        format!("{}, {}, {threads}", self.cpu, self.mlp_isa)
    }
}

/// The first `model name` of a `/proc/cpuinfo` text, its runs of spaces folded to one.
fn cpu_model(cpuinfo: Option<&str>) -> Option<String> {
    let line = cpuinfo?.lines().find(|l| l.split(':').next().is_some_and(|k| k.trim() == "model name"))?;
    let name = line.split_once(':')?.1.split_whitespace().collect::<Vec<_>>().join(" ");
    (!name.is_empty()).then_some(name)
}

/// The machines a run directory's `run.json` records (a search's or a comparison's: `machine` for
/// the invocation that created it, `resumed[].machine` for each later one), as [`distinct`]
/// labels; none when the file or the records are missing.
pub fn of_run(dir: &Path) -> Vec<String> {
    let Ok(info) = crate::store::read_json::<serde_json::Value>(&dir.join("run.json")) else { return Vec::new() };
    let parse = |v: Option<&serde_json::Value>| v.and_then(|m| serde_json::from_value::<Machine>(m.clone()).ok());
    let resumed = info.get("resumed").and_then(|r| r.as_array()).into_iter().flatten();
    // Invocations that recorded none (runs made before machines were recorded) are left out.
    let all = std::iter::once(info.get("machine")).chain(resumed.map(|e| e.get("machine")));
    distinct(all.filter_map(parse).map(|m| m.label()))
}

/// Machine labels in order of first appearance, each once: what a report prints beside a wall
/// time made of several invocations (or runs).
pub fn distinct(labels: impl IntoIterator<Item = String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for l in labels {
        if !out.contains(&l) {
            out.push(l);
        }
    }
    out
}

/// ` on <machine>` (or ` on <a> and <b>` when invocations ran on several), to follow a wall
/// time in a report; empty when no invocation recorded its machine.
pub fn wall_suffix(labels: &[String]) -> String {
    match labels {
        [] => String::new(),
        [one] => format!(" on {one}"),
        [init @ .., last] => {
            format!(" on {} and {last} (its invocations differ in CPU, kernels or threads)", init.join(", "))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CPUINFO: &str = "processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC   7551\nflags\t\t: fpu\n\n\
                           processor\t: 1\nmodel name\t: AMD EPYC 7551\n";

    #[test]
    fn the_cpu_model_is_the_first_model_name_with_spaces_folded() {
        assert_eq!(cpu_model(Some(CPUINFO)).as_deref(), Some("AMD EPYC 7551"));
        assert_eq!(cpu_model(Some("processor : 0\nmodel name\t:   \n")), None);
        assert_eq!(cpu_model(Some("Processor\t: AArch64\n")), None);
        assert_eq!(cpu_model(None), None);
    }

    fn machine(cpu: &str, isa: &str, threads: usize) -> Machine {
        Machine { cpu: cpu.into(), cpus: 2, threads, mlp_isa: isa.into(), extra_trees_isa: isa.into() }
    }

    #[test]
    fn labels_name_the_cpu_the_mlp_level_and_the_threads() {
        assert_eq!(machine("AMD EPYC", "avx2", 2).label(), "AMD EPYC, avx2, 2 threads");
        assert_eq!(machine("x86_64", "portable", 1).label(), "x86_64, portable, 1 thread");
    }

    #[test]
    fn a_wall_time_names_each_machine_once_and_says_when_there_were_several() {
        let (a, b) = (machine("Xeon", "avx512", 2), machine("EPYC", "avx2", 2));
        assert_eq!(wall_suffix(&distinct([])), "");
        assert_eq!(wall_suffix(&distinct([a.label(), a.label()])), " on Xeon, avx512, 2 threads");
        let two = wall_suffix(&distinct([a.label(), b.label(), a.label()]));
        assert_eq!(
            two,
            " on Xeon, avx512, 2 threads and EPYC, avx2, 2 threads (its invocations differ in CPU, kernels or threads)"
        );
    }

    #[test]
    fn this_machine_is_described() {
        let m = Machine::this();
        assert!(!m.cpu.is_empty() && m.cpus >= 1 && m.threads >= 1);
        assert!(["avx512", "avx2", "portable"].contains(&m.mlp_isa.as_str()), "{}", m.mlp_isa);
    }
}
