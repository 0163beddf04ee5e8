//! Isomap (Tenenbaum et al.; thesis §2.5.2): neighbourhood graph, all-pairs shortest paths, MDS.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use nalgebra::DMatrix;
use rayon::prelude::*;

use crate::error::{ReduceError, Result};
use crate::mds::{classical_mds, Embedding};

/// How the neighbourhood graph's edges are chosen (seed: "K – minimum neighbourhood size and
/// ε – maximum neighbourhood distance").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Neighbourhood {
    /// Edge `(i, j)` when `j` is one of the `k` nearest neighbours of `i` (or vice versa).
    Knn(usize),
    /// Edge `(i, j)` when `d(i, j) < ε`.
    Epsilon(f64),
    /// The union of both rules.
    KnnOrEpsilon {
        /// Neighbour count.
        k: usize,
        /// Distance threshold.
        epsilon: f64,
    },
}

impl Neighbourhood {
    fn grown(self, n: usize) -> Option<Neighbourhood> {
        match self {
            Neighbourhood::Knn(k) if k + 1 < n => Some(Neighbourhood::Knn(k + 1)),
            Neighbourhood::Epsilon(e) => Some(Neighbourhood::Epsilon(e * 1.25)),
            Neighbourhood::KnnOrEpsilon { k, epsilon } => Some(Neighbourhood::KnnOrEpsilon {
                k: (k + 1).min(n - 1),
                epsilon: epsilon * 1.25,
            }),
            _ => None,
        }
    }
}

/// What to do when the graph has several connected components (the thesis's three options, plus
/// refusing).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DisconnectedPolicy {
    /// Return [`ReduceError::Disconnected`].
    Fail,
    /// Option (1): remove the disconnected node sets, keep the largest component.
    KeepLargest,
    /// Option (2): analyse each component separately.
    EmbedSeparately,
    /// Option (3): increase K and/or ε until the graph is connected.
    GrowNeighbourhood,
}

/// Isomap embedding of one connected component.
#[derive(Debug, Clone)]
pub struct ComponentEmbedding {
    /// Indices of the input points in this component (increasing).
    pub indices: Vec<usize>,
    /// Embedding of those points (row `r` = point `indices[r]`).
    pub embedding: Embedding,
}

/// Result of [`isomap`].
#[derive(Debug, Clone)]
pub struct Isomap {
    /// One entry per embedded component (a single one unless `EmbedSeparately` was needed).
    pub components: Vec<ComponentEmbedding>,
    /// The neighbourhood rule finally used (differs from the request after growing).
    pub neighbourhood: Neighbourhood,
    /// Number of connected components of the graph finally used.
    pub graph_components: usize,
}

/// Undirected weighted adjacency lists of the neighbourhood graph of a distance matrix.
pub fn neighbourhood_graph(
    dist: &DMatrix<f64>,
    rule: Neighbourhood,
) -> Result<Vec<Vec<(usize, f64)>>> {
    let n = dist.nrows();
    ReduceError::check_size("distance matrix columns", n, dist.ncols())?;
    if dist.iter().any(|v| !v.is_finite()) {
        return Err(ReduceError::NonFinite("distance matrix"));
    }
    let (k, eps) = match rule {
        Neighbourhood::Knn(k) => (k, f64::NEG_INFINITY),
        Neighbourhood::Epsilon(e) => (0, e),
        Neighbourhood::KnnOrEpsilon { k, epsilon } => (k, epsilon),
    };
    if k >= n.max(1) || eps.is_nan() || (k == 0 && eps <= 0.0) {
        return Err(ReduceError::InvalidParameter(format!(
            "neighbourhood {rule:?} for {n} points"
        )));
    }
    let mut edge = vec![false; n * n];
    for i in 0..n {
        let mut order: Vec<usize> = (0..n).filter(|&j| j != i).collect();
        order.sort_by(|&a, &b| dist[(i, a)].total_cmp(&dist[(i, b)]).then(a.cmp(&b)));
        for &j in order.iter().take(k) {
            edge[i * n + j] = true;
            edge[j * n + i] = true;
        }
        for j in 0..n {
            if j != i && dist[(i, j)] < eps {
                edge[i * n + j] = true;
                edge[j * n + i] = true;
            }
        }
    }
    Ok((0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| edge[i * n + j])
                .map(|j| (j, dist[(i, j)]))
                .collect()
        })
        .collect())
}

#[derive(PartialEq)]
struct Item(f64, usize);
impl Eq for Item {}
impl PartialOrd for Item {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Item {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

/// All-pairs shortest path lengths (Dijkstra from every node, in parallel); `∞` where no path.
pub fn geodesic_distances(graph: &[Vec<(usize, f64)>]) -> DMatrix<f64> {
    let n = graph.len();
    let rows: Vec<Vec<f64>> = (0..n)
        .into_par_iter()
        .map(|s| {
            let mut d = vec![f64::INFINITY; n];
            d[s] = 0.0;
            let mut heap = BinaryHeap::new();
            heap.push(Item(0.0, s));
            while let Some(Item(du, u)) = heap.pop() {
                if du > d[u] {
                    continue;
                }
                for &(v, w) in &graph[u] {
                    let nd = du + w;
                    if nd < d[v] {
                        d[v] = nd;
                        heap.push(Item(nd, v));
                    }
                }
            }
            d
        })
        .collect();
    DMatrix::from_fn(n, n, |i, j| rows[i][j])
}

/// Connected components (lists of node indices, largest first) of an undirected graph.
pub fn connected_components(graph: &[Vec<(usize, f64)>]) -> Vec<Vec<usize>> {
    let n = graph.len();
    let mut label = vec![usize::MAX; n];
    let mut comps = Vec::new();
    for s in 0..n {
        if label[s] != usize::MAX {
            continue;
        }
        let id = comps.len();
        let mut stack = vec![s];
        let mut members = Vec::new();
        label[s] = id;
        while let Some(u) = stack.pop() {
            members.push(u);
            for &(v, _) in &graph[u] {
                if label[v] == usize::MAX {
                    label[v] = id;
                    stack.push(v);
                }
            }
        }
        members.sort_unstable();
        comps.push(members);
    }
    comps.sort_by(|a, b| b.len().cmp(&a.len()).then(a[0].cmp(&b[0])));
    comps
}

/// Isomap of the points with pairwise distances `dist`, embedded in `d` dimensions.
pub fn isomap(
    dist: &DMatrix<f64>,
    rule: Neighbourhood,
    d: usize,
    policy: DisconnectedPolicy,
) -> Result<Isomap> {
    let n = dist.nrows();
    let mut rule = rule;
    let (graph, comps) = loop {
        let graph = neighbourhood_graph(dist, rule)?;
        let comps = connected_components(&graph);
        if comps.len() == 1 || policy != DisconnectedPolicy::GrowNeighbourhood {
            break (graph, comps);
        }
        rule = rule.grown(n).ok_or(ReduceError::Disconnected {
            components: comps.len(),
        })?;
        tracing::debug!(
            ?rule,
            components = comps.len(),
            "isomap: growing neighbourhood"
        );
    };
    let graph_components = comps.len();
    let chosen: Vec<Vec<usize>> = match (graph_components, policy) {
        (1, _) => comps,
        (c, DisconnectedPolicy::Fail) => return Err(ReduceError::Disconnected { components: c }),
        (_, DisconnectedPolicy::KeepLargest) => vec![comps[0].clone()],
        (_, DisconnectedPolicy::EmbedSeparately) => comps,
        (c, DisconnectedPolicy::GrowNeighbourhood) => {
            return Err(ReduceError::Disconnected { components: c })
        }
    };
    let geo = geodesic_distances(&graph);
    let mut components = Vec::new();
    for idx in chosen {
        if idx.len() <= d {
            if policy == DisconnectedPolicy::EmbedSeparately && idx.len() < 2 {
                // A lone point embeds at the origin.
                components.push(ComponentEmbedding {
                    embedding: Embedding {
                        coords: DMatrix::zeros(idx.len(), d),
                        eigenvalues: vec![0.0; idx.len()],
                    },
                    indices: idx,
                });
                continue;
            }
            return Err(ReduceError::NotEnoughData(format!(
                "component of {} points cannot be embedded in {d} dimensions",
                idx.len()
            )));
        }
        let sub = DMatrix::from_fn(idx.len(), idx.len(), |a, b| geo[(idx[a], idx[b])]);
        let embedding = classical_mds(&sub, d)?;
        components.push(ComponentEmbedding {
            indices: idx,
            embedding,
        });
    }
    Ok(Isomap {
        components,
        neighbourhood: rule,
        graph_components,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mds::euclidean_distances;

    /// Two parallel lines of points far apart.
    fn two_clusters() -> DMatrix<f64> {
        let mut p = DMatrix::zeros(20, 2);
        for i in 0..10 {
            p[(i, 0)] = i as f64;
            p[(10 + i, 0)] = i as f64 * 1.1;
            p[(10 + i, 1)] = 100.0;
        }
        p
    }

    #[test]
    fn geodesics_on_a_path_graph_are_arc_lengths() {
        // Points on a semicircle: graph distance with 2-NN approximates the arc length.
        let n = 50;
        let pts = DMatrix::from_fn(n, 2, |i, c| {
            let t = std::f64::consts::PI * i as f64 / (n - 1) as f64;
            if c == 0 {
                t.cos()
            } else {
                t.sin()
            }
        });
        let g = geodesic_distances(
            &neighbourhood_graph(&euclidean_distances(&pts), Neighbourhood::Knn(2)).unwrap(),
        );
        let arc = std::f64::consts::PI;
        assert!(
            (g[(0, n - 1)] - arc).abs() < 1e-3 * arc,
            "{}",
            g[(0, n - 1)]
        );
        let iso = isomap(
            &euclidean_distances(&pts),
            Neighbourhood::Knn(2),
            1,
            DisconnectedPolicy::Fail,
        )
        .unwrap();
        // The 1-D embedding unrolls the arc: coordinates are monotone in the arc parameter.
        let x = iso.components[0].embedding.coords.column(0);
        let s = (x[n - 1] - x[0]).signum();
        assert!((1..n).all(|i| (x[i] - x[i - 1]) * s > 0.0));
    }

    #[test]
    fn the_three_disconnected_policies() {
        let dist = euclidean_distances(&two_clusters());
        let rule = Neighbourhood::Knn(3);
        assert!(matches!(
            isomap(&dist, rule, 1, DisconnectedPolicy::Fail),
            Err(ReduceError::Disconnected { components: 2 })
        ));
        let keep = isomap(&dist, rule, 1, DisconnectedPolicy::KeepLargest).unwrap();
        assert_eq!(keep.components.len(), 1);
        assert_eq!(keep.components[0].indices, (0..10).collect::<Vec<_>>());
        let sep = isomap(&dist, rule, 1, DisconnectedPolicy::EmbedSeparately).unwrap();
        assert_eq!(sep.components.len(), 2);
        assert_eq!(
            sep.components
                .iter()
                .map(|c| c.indices.len())
                .sum::<usize>(),
            20
        );
        let grown = isomap(&dist, rule, 1, DisconnectedPolicy::GrowNeighbourhood).unwrap();
        assert_eq!(grown.graph_components, 1);
        match grown.neighbourhood {
            Neighbourhood::Knn(k) => {
                assert!(k >= 10, "needs at least 10 neighbours to bridge, got {k}")
            }
            other => panic!("unexpected rule {other:?}"),
        }
        assert_eq!(grown.components[0].indices.len(), 20);
    }

    #[test]
    fn epsilon_graph_edges_respect_threshold() {
        let dist = euclidean_distances(&two_clusters());
        let g = neighbourhood_graph(&dist, Neighbourhood::Epsilon(1.05)).unwrap();
        for (i, adj) in g.iter().enumerate() {
            for &(j, w) in adj {
                assert!(w < 1.05 && i != j);
            }
        }
        assert!(neighbourhood_graph(&dist, Neighbourhood::Knn(20)).is_err());
    }
}
