//! The Common Wavelet Coefficient Tree (thesis §6.2 and appendix A.3).

use crate::cwb::{CommonBasis, Layout};
use crate::error::{Result, WaveletError};
use crate::transform::Wavelet;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// One node of the tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Node {
    /// Bit `c` set when child `c = (bx << 2) | (by << 1) | bz` exists.
    child_mask: u8,
    /// Bit `m` set when basis type `m` (0 = scaling, 1..=7 = wavelets) has a row.
    kind_mask: u8,
    /// Index of the first existing child in `nodes`.
    first_child: u32,
    /// Index of the first row of this node in the coefficient table.
    first_row: u32,
}

/// Storage figures of a tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TreeStorage {
    /// Number of nodes.
    pub nodes: usize,
    /// Number of coefficient rows (= basis size).
    pub rows: usize,
    /// Number of represented functions (values per row).
    pub functions: usize,
    /// Bytes of the node array.
    pub node_bytes: usize,
    /// Bytes of the coefficient table (f32).
    pub coefficient_bytes: usize,
    /// Bytes of the same functions stored densely as f32 tables.
    pub dense_bytes: usize,
}

impl TreeStorage {
    /// Total bytes (nodes + coefficients).
    pub fn total_bytes(&self) -> usize {
        self.node_bytes + self.coefficient_bytes
    }
}

/// A wavelet coefficient tree shared by many functions: the Common Wavelet Coefficient Tree of
/// thesis §6.2 and appendix A.3.
///
/// One node per (level, offset) of the nonstandard Haar decomposition that carries a CWB
/// coefficient or has a descendant that does. A node stores, for each of its present basis
/// types (the 7 wavelets of (6.4), plus the scaling function at the root), one *row*: the
/// coefficients of that basis function in every represented function (e.g. R, G, B of every
/// PCA component). Children are stored contiguously in breadth-first order (Morton order within
/// a level), addressed by an 8-bit child mask.
///
/// Evaluating at a cell descends from the root along the single path of nodes whose support
/// contains the cell — at most log2(side) nodes — and accumulates `±w^{-3/2} · row` at each, so
/// one traversal yields the values of all represented functions at once.
///
/// # Examples
///
/// ```
/// use wavelet::{CoefficientTree, CommonBasis, Layout, Wavelet};
///
/// // two functions on a 4 × 4 × 8 table, kept losslessly, evaluated together
/// let layout = Layout { side: 16, extent: [4, 4, 8], wavelet: Wavelet::Haar };
/// let f: Vec<f32> = (0..128).map(|i| (i % 5) as f32).collect();
/// let g: Vec<f32> = (0..128).map(|i| 2.0 + (i / 32) as f32).collect();
/// let (basis, _) = CommonBasis::build(layout, &[&f, &g], 0.0).unwrap();
/// let tree = CoefficientTree::from_functions(&basis, &[&f, &g]).unwrap();
/// assert_eq!(tree.functions(), 2);
/// let mut out = [0.0f32; 2];
/// tree.eval_cell([1, 2, 3], &mut out).unwrap(); // table index (1 · 4 + 2) · 8 + 3 = 51
/// assert!((out[0] - f[51]).abs() < 1e-4 && (out[1] - g[51]).abs() < 1e-4);
/// ```
#[derive(Debug, Clone)]
pub struct CoefficientTree {
    layout: Layout,
    levels: u32,
    functions: usize,
    nodes: Vec<Node>,
    /// Basis index (position in [`CommonBasis::indices`]) of each row.
    row_basis: Vec<u32>,
    rows: Vec<f32>,
    /// `w^{-3/2}` per level, `w = side >> level`.
    amplitude: Vec<f32>,
}

/// Morton key of a node offset at `level` (3 bits per level, θh bit highest).
fn morton(offset: [u32; 3], level: u32) -> u64 {
    let mut k = 0u64;
    for b in (0..level).rev() {
        let code =
            ((offset[0] >> b) & 1) << 2 | ((offset[1] >> b) & 1) << 1 | ((offset[2] >> b) & 1);
        k = (k << 3) | code as u64;
    }
    k
}

impl CoefficientTree {
    /// Builds the tree of a Haar basis from coefficient vectors: `coefficients[j][i]` is the
    /// coefficient of basis function `i` in represented function `j`.
    pub fn new(basis: &CommonBasis, coefficients: &[Vec<f32>]) -> Result<Self> {
        if coefficients.is_empty() {
            return Err(WaveletError::NoFunctions);
        }
        Self::build(basis, coefficients)
    }

    /// The tree of a Haar basis without any represented function: only the node structure,
    /// for [`Self::basis_at_cell`] (the rows of the matrix H of seed (6.7)).
    pub fn structure(basis: &CommonBasis) -> Result<Self> {
        Self::build(basis, &[])
    }

    fn build(basis: &CommonBasis, coefficients: &[Vec<f32>]) -> Result<Self> {
        let layout = basis.layout();
        if layout.wavelet != Wavelet::Haar {
            // Point evaluation along one root-to-leaf path needs disjoint supports per level.
            return Err(WaveletError::UnsupportedWavelet(
                "the coefficient tree needs Haar wavelets",
            ));
        }
        for c in coefficients {
            if c.len() != basis.len() {
                return Err(WaveletError::Length {
                    expected: basis.len(),
                    found: c.len(),
                });
            }
            if let Some(index) = crate::cube::first_non_finite(c) {
                return Err(WaveletError::NonFinite { index });
            }
        }
        let levels = layout.side.trailing_zeros();
        let m = coefficients.len();
        // Per level: Morton key -> basis index per type.
        let mut per_level: Vec<BTreeMap<u64, [Option<u32>; 8]>> =
            (0..levels).map(|_| BTreeMap::new()).collect();
        for i in 0..basis.len() {
            let a = basis.address(i);
            let key = morton(a.offset, a.level);
            per_level[a.level as usize].entry(key).or_insert([None; 8])[a.kind as usize] =
                Some(i as u32);
        }
        per_level[0].entry(0).or_insert([None; 8]);
        for l in (1..levels as usize).rev() {
            let parents: Vec<u64> = per_level[l].keys().map(|k| k >> 3).collect();
            for p in parents {
                per_level[l - 1].entry(p).or_insert([None; 8]);
            }
        }
        let total_nodes: usize = per_level.iter().map(|m| m.len()).sum();
        let mut nodes = Vec::with_capacity(total_nodes);
        let mut rows = Vec::with_capacity(basis.len() * m);
        let mut row_basis = Vec::with_capacity(basis.len());
        let mut level_start = 0usize;
        for l in 0..levels as usize {
            let next_start = level_start + per_level[l].len();
            let mut child_keys = per_level
                .get(l + 1)
                .map(|c| c.keys().copied().collect::<Vec<u64>>())
                .unwrap_or_default()
                .into_iter()
                .enumerate()
                .peekable();
            for (&key, kinds) in &per_level[l] {
                let mut node = Node {
                    first_row: row_basis.len() as u32,
                    ..Node::default()
                };
                for (kind, slot) in kinds.iter().enumerate() {
                    if let Some(bi) = slot {
                        node.kind_mask |= 1 << kind;
                        rows.extend(coefficients.iter().map(|c| c[*bi as usize]));
                        row_basis.push(*bi);
                    }
                }
                let mut first = true;
                while let Some(&(ci, ck)) = child_keys.peek() {
                    if ck >> 3 != key {
                        break;
                    }
                    if first {
                        node.first_child = (next_start + ci) as u32;
                        first = false;
                    }
                    node.child_mask |= 1 << (ck & 7);
                    child_keys.next();
                }
                nodes.push(node);
            }
            level_start = next_start;
        }
        let amplitude = (0..levels)
            .map(|l| {
                let w = (layout.side >> l) as f64;
                (1.0 / (w * w * w).sqrt()) as f32
            })
            .collect();
        Ok(Self {
            layout,
            levels,
            functions: m,
            nodes,
            row_basis,
            rows,
            amplitude,
        })
    }

    /// Builds the tree of a Haar basis for tabulated functions (each of the basis layout's
    /// extent), computing their coefficients in parallel.
    pub fn from_functions(basis: &CommonBasis, functions: &[&[f32]]) -> Result<Self> {
        let coefficients = functions
            .par_iter()
            .map(|f| basis.coefficients(f))
            .collect::<Result<Vec<_>>>()?;
        Self::new(basis, &coefficients)
    }

    /// Layout of the underlying basis.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Number of represented functions (length of the output of an evaluation).
    pub fn functions(&self) -> usize {
        self.functions
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Storage figures.
    pub fn storage(&self) -> TreeStorage {
        TreeStorage {
            nodes: self.nodes.len(),
            rows: self.row_basis.len(),
            functions: self.functions,
            node_bytes: self.nodes.len() * std::mem::size_of::<Node>()
                + self.row_basis.len() * std::mem::size_of::<u32>(),
            coefficient_bytes: self.rows.len() * std::mem::size_of::<f32>(),
            dense_bytes: self.functions * self.layout.table_len() * std::mem::size_of::<f32>(),
        }
    }

    /// Values of all represented functions at cell `(x, y, z)` of the cube, written to `out`
    /// (length [`Self::functions`]). Returns the number of nodes visited.
    pub fn eval_cell(&self, cell: [usize; 3], out: &mut [f32]) -> Result<usize> {
        if out.len() != self.functions {
            return Err(WaveletError::Length {
                expected: self.functions,
                found: out.len(),
            });
        }
        self.check_cell(cell)?;
        Ok(self.eval_cell_unchecked(cell, out))
    }

    /// Values at MERL bin indices (θh, θd, φd); the layout must hold the table at the origin
    /// (any extent covering the indices).
    pub fn eval_bin(
        &self,
        i_th: usize,
        i_td: usize,
        i_pd: usize,
        out: &mut [f32],
    ) -> Result<usize> {
        self.eval_cell([i_th, i_td, i_pd], out)
    }

    /// Values at Rusinkiewicz angles, with the MERL bin mapping of [`brdf::MerlTable`] (nearest
    /// bin, φd folded by reciprocity). Meaningful for the MERL layout.
    pub fn eval_angles(
        &self,
        theta_h: f64,
        theta_d: f64,
        phi_d: f64,
        out: &mut [f32],
    ) -> Result<usize> {
        use brdf::{phi_diff_index, theta_diff_index, theta_half_index};
        self.eval_cell(
            [
                theta_half_index(theta_h),
                theta_diff_index(theta_d),
                phi_diff_index(phi_d),
            ],
            out,
        )
    }

    fn eval_cell_unchecked(&self, cell: [usize; 3], out: &mut [f32]) -> usize {
        out.fill(0.0);
        let m = self.functions;
        self.for_each_term(cell, |row, s| {
            let r = &self.rows[row * m..(row + 1) * m];
            for (o, &v) in out.iter_mut().zip(r) {
                *o += s * v;
            }
        })
    }

    /// The basis functions that are non-zero at cell `(x, y, z)`, as (basis index, value)
    /// pairs appended to `out` (after clearing it): one row of the matrix H of seed (6.7),
    /// found with one root-to-leaf traversal (at most 8 entries per level).
    pub fn basis_at_cell(&self, cell: [usize; 3], out: &mut Vec<(u32, f32)>) -> Result<()> {
        out.clear();
        self.check_cell(cell)?;
        self.for_each_term(cell, |row, s| out.push((self.row_basis[row], s)));
        Ok(())
    }

    fn check_cell(&self, cell: [usize; 3]) -> Result<()> {
        let side = self.layout.side;
        if cell.iter().any(|&c| c >= side) {
            return Err(WaveletError::IndexOutOfRange {
                index: cell.iter().copied().max().unwrap_or(0),
                len: side,
            });
        }
        Ok(())
    }

    /// Walks from the root to the deepest node holding `cell` and calls `term(row, value)` for
    /// every stored basis function on the way: its row in the tree and its value at the cell
    /// (± the level's amplitude, the sign given by the cell's octant). Returns the number of
    /// nodes visited.
    #[inline(always)]
    fn for_each_term(&self, cell: [usize; 3], mut term: impl FnMut(usize, f32)) -> usize {
        let mut node = 0usize;
        let mut visited = 0;
        for l in 0..self.levels {
            let nd = self.nodes[node];
            visited += 1;
            let shift = self.levels - 1 - l;
            let code = child_code(cell, shift);
            let amp = self.amplitude[l as usize];
            let mut row = nd.first_row as usize;
            let mut mask = nd.kind_mask;
            while mask != 0 {
                let kind = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let s = if (kind & code).count_ones() % 2 == 1 {
                    -amp
                } else {
                    amp
                };
                term(row, s);
                row += 1;
            }
            let bit = 1u8 << code;
            if nd.child_mask & bit == 0 {
                break;
            }
            node = nd.first_child as usize + (nd.child_mask & (bit - 1)).count_ones() as usize;
        }
        visited
    }

    /// Evaluates many cells in parallel; returns `cells.len() × functions` values, cell-major.
    pub fn eval_cells(&self, cells: &[[usize; 3]]) -> Result<Vec<f32>> {
        let m = self.functions;
        let mut out = vec![0.0f32; cells.len() * m];
        out.par_chunks_mut(m)
            .zip(cells.par_iter())
            .try_for_each(|(o, c)| self.eval_cell(*c, o).map(|_| ()))?;
        Ok(out)
    }
}

/// Child code `(bx << 2) | (by << 1) | bz` of a cell at bit `shift`.
#[inline]
fn child_code(cell: [usize; 3], shift: u32) -> usize {
    ((cell[0] >> shift) & 1) << 2 | ((cell[1] >> shift) & 1) << 1 | ((cell[2] >> shift) & 1)
}
