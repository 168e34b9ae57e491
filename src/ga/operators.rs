//! The genetic operators of thesis Appendix C (SPEC §5): ranking, elitism, uniform parent
//! selection from the best half, interval crossover and per-gene resampling mutation.
//!
//! Every draw comes from a stream named by (seed, generation, child), so a generation is a pure
//! function of the previous one and its fitnesses.

use super::chromosome::{Chromosome, GENES, GeneRanges};
use crate::rng::{self, Rng, int_in, stream, unit};
use serde::{Deserialize, Serialize};

/// GA parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaParams {
    /// Individuals per generation.
    pub population: usize,
    /// Fraction of the best passed on unchanged.
    pub elitism: f64,
    /// Fraction of the best that parents are drawn from.
    pub parent_pool: f64,
    /// Probability that a child is mutated.
    pub mutation: f64,
    /// Probability that each gene of a mutated child is resampled over its full range.
    pub gene_resampling: f64,
}

impl Default for GaParams {
    fn default() -> Self {
        GaParams { population: 20, elitism: 0.2, parent_pool: 0.5, mutation: 0.8, gene_resampling: 0.2 }
    }
}

impl GaParams {
    /// Number of elites (rounded, at least 0, at most the population).
    pub fn n_elites(&self) -> usize {
        ((self.population as f64 * self.elitism).round() as usize).min(self.population)
    }

    /// Number of individuals parents are drawn from (at least 1).
    pub fn n_parents(&self) -> usize {
        ((self.population as f64 * self.parent_pool).round() as usize).clamp(1, self.population)
    }
}

/// Indices of `fitness` from best to worst; ties keep the lower index first.
pub fn rank(fitness: &[f64]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..fitness.len()).collect();
    // A stable sort on descending fitness keeps ties in index order.
    idx.sort_by(|&a, &b| fitness[b].total_cmp(&fitness[a]));
    idx
}

/// A gene drawn uniformly over its full range.
fn draw_gene(rng: &mut Rng, [lo, hi]: [i64; 2]) -> i64 {
    int_in(rng, lo, hi)
}

/// A chromosome with every gene uniform over its range, drawn in gene order.
fn uniform(r: &mut Rng, bounds: &[[i64; 2]; GENES]) -> Chromosome {
    let mut c = [0; GENES];
    for (g, b) in c.iter_mut().zip(bounds) {
        *g = draw_gene(r, *b);
    }
    c
}

/// The initial population: every gene uniform over its range.
pub fn initial_population(seed: u64, ranges: &GeneRanges, size: usize) -> Vec<Chromosome> {
    let bounds = ranges.bounds();
    (0..size).map(|i| uniform(&mut stream(seed, crate::rng::purpose::GA_INIT, &[i as u64]), &bounds)).collect()
}

/// Generation `generation` (≥ 1) of a random search (`search.strategy: random`): every gene
/// uniform over its range, as in the initial population, from a stream of its own per generation
/// and individual.
pub fn random_generation(seed: u64, generation: usize, ranges: &GeneRanges, size: usize) -> Vec<Chromosome> {
    let bounds = ranges.bounds();
    (0..size)
        .map(|i| uniform(&mut stream(seed, crate::rng::purpose::GA_RANDOM, &[generation as u64, i as u64]), &bounds))
        .collect()
}

/// How a child came about (logged for inspection).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Birth {
    /// Indices (in the previous generation) of the two parents.
    pub parents: [usize; 2],
    /// The child before mutation.
    pub crossed: Chromosome,
    /// Whether it was mutated.
    pub mutated: bool,
}

/// The next generation: elites first (in rank order, unchanged), then the children.
/// Only `eligible` individuals (all of them unless pruning removed some) are elites or parents.
/// Returns the population and, for each child, its [`Birth`].
pub fn next_generation(
    seed: u64,
    generation: usize,
    population: &[Chromosome],
    fitness: &[f64],
    eligible: &[bool],
    ranges: &GeneRanges,
    ga: &GaParams,
) -> (Vec<Chromosome>, Vec<Birth>) {
    let mut order: Vec<usize> = rank(fitness).into_iter().filter(|&i| eligible[i]).collect();
    if order.is_empty() {
        // Nobody eligible (not reachable: elites are never pruned); fall back to every individual.
        order = rank(fitness);
    }
    let bounds = ranges.bounds();
    let mut next: Vec<Chromosome> = order.iter().take(ga.n_elites()).map(|&i| population[i]).collect();
    let pool = &order[..ga.n_parents().min(order.len())];
    let mut births = Vec::new();
    let mut child = 0u64;
    while next.len() < ga.population {
        let mut r = stream(seed, crate::rng::purpose::GA_BREED, &[generation as u64, child]);
        child += 1;
        let p1 = pool[rng::below(&mut r, pool.len() as u64) as usize];
        let p2 = pool[rng::below(&mut r, pool.len() as u64) as usize];
        let mut c = [0; GENES];
        for (g, gene) in c.iter_mut().enumerate() {
            let (a, b) = (population[p1][g], population[p2][g]);
            *gene = int_in(&mut r, a.min(b), a.max(b));
        }
        let crossed = c;
        let mutated = unit(&mut r) < ga.mutation;
        if mutated {
            for (g, b) in c.iter_mut().zip(bounds) {
                if unit(&mut r) < ga.gene_resampling {
                    *g = draw_gene(&mut r, b);
                }
            }
        }
        births.push(Birth { parents: [p1, p2], crossed, mutated });
        next.push(c);
    }
    (next, births)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> (GeneRanges, GaParams, Vec<Chromosome>, Vec<f64>) {
        let r = GeneRanges::default();
        let ga = GaParams::default();
        let pop = initial_population(3, &r, ga.population);
        let fit: Vec<f64> = (0..ga.population).map(|i| ((i * 7) % 20) as f64).collect();
        (r, ga, pop, fit)
    }

    #[test]
    fn rank_breaks_ties_by_index() {
        assert_eq!(rank(&[1.0, 3.0, 3.0, f64::NEG_INFINITY, 2.0]), vec![1, 2, 4, 0, 3]);
    }

    #[test]
    fn initial_population_is_in_range_and_seeded() {
        let (r, ga, pop, _) = setup();
        assert!(pop.iter().all(|c| r.contains(c)));
        assert_eq!(pop, initial_population(3, &r, ga.population));
        assert_ne!(pop, initial_population(4, &r, ga.population));
    }

    #[test]
    fn elites_pass_unchanged_and_children_come_from_the_best_half() {
        let (r, ga, pop, fit) = setup();
        let (next, births) = next_generation(3, 0, &pop, &fit, &vec![true; pop.len()], &r, &ga);
        assert_eq!(next.len(), 20);
        let order = rank(&fit);
        for e in 0..4 {
            assert_eq!(next[e], pop[order[e]], "elite {e}");
        }
        assert_eq!(births.len(), 16);
        let best_half = &order[..10];
        for (b, c) in births.iter().zip(&next[4..]) {
            assert!(b.parents.iter().all(|p| best_half.contains(p)));
            for (g, gene) in b.crossed.iter().enumerate() {
                let (x, y) = (pop[b.parents[0]][g], pop[b.parents[1]][g]);
                assert!(x.min(y) <= *gene && *gene <= x.max(y), "gene {g} outside its parents");
            }
            if !b.mutated {
                assert_eq!(&b.crossed, c);
            }
            assert!(r.contains(c));
        }
    }

    #[test]
    fn ineligible_individuals_are_never_elites_or_parents() {
        let (r, ga, pop, fit) = setup();
        // The best twelve are ineligible (say, pruned): elites and parents come from the rest.
        let order = rank(&fit);
        let mut eligible = vec![true; pop.len()];
        for &i in &order[..12] {
            eligible[i] = false;
        }
        let (next, births) = next_generation(3, 0, &pop, &fit, &eligible, &r, &ga);
        assert_eq!(next.len(), 20);
        for e in 0..4 {
            assert_eq!(next[e], pop[order[12 + e]], "elite {e}");
        }
        for b in &births {
            assert!(b.parents.iter().all(|&p| eligible[p] && order[12..].contains(&p)));
        }
    }

    #[test]
    fn mutation_frequencies_match_the_spec() {
        let (r, ga, pop, fit) = setup();
        let (mut children, mut mutated, mut genes_changed_draws) = (0usize, 0usize, 0usize);
        let mut resampled_checks = 0usize;
        // Resampling draws over the full range can land on the same value; measure the draw rate
        // with a range where that is rare (a_δ: 90 values) among mutated children.
        for generation in 0..400 {
            let (next, births) = next_generation(11, generation, &pop, &fit, &[true; 20], &r, &ga);
            for (b, c) in births.iter().zip(&next[4..]) {
                children += 1;
                if b.mutated {
                    mutated += 1;
                    resampled_checks += 1;
                    if b.crossed[1] != c[1] {
                        genes_changed_draws += 1;
                    }
                }
            }
        }
        let p_mut = mutated as f64 / children as f64;
        assert!((p_mut - 0.8).abs() < 0.02, "mutation rate {p_mut}");
        // P(gene changes | mutated) = 0.2 · (1 − 1/90).
        let p_gene = genes_changed_draws as f64 / resampled_checks as f64;
        assert!((p_gene - 0.2 * (1.0 - 1.0 / 90.0)).abs() < 0.02, "gene resampling rate {p_gene}");
    }
}
