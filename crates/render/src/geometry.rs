//! Rays, spheres, triangles and a bounding volume hierarchy (binned SAH).

use brdf::Vec3;

/// A ray `origin + t · direction` (direction unit length).
#[derive(Debug, Clone, Copy)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3,
    /// Unit direction.
    pub direction: Vec3,
}

impl Ray {
    /// A new ray; `direction` must be normalised.
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        Self { origin, direction }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f64) -> Vec3 {
        self.origin + self.direction * t
    }
}

/// Axis-aligned bounding box.
#[derive(Debug, Clone, Copy)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box.
    pub fn empty() -> Self {
        Self {
            min: Vec3::repeat(f64::INFINITY),
            max: Vec3::repeat(f64::NEG_INFINITY),
        }
    }

    /// Grows the box to contain `p`.
    pub fn grow(&mut self, p: &Vec3) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }

    /// Union of two boxes.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.inf(&o.min),
            max: self.max.sup(&o.max),
        }
    }

    /// Centre point.
    pub fn centroid(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Surface area (zero for the empty box).
    pub fn area(&self) -> f64 {
        let d = self.max - self.min;
        if d.x < 0.0 || d.y < 0.0 || d.z < 0.0 {
            0.0
        } else {
            2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
        }
    }

    #[inline]
    fn hit(&self, origin: &Vec3, inv_dir: &Vec3, t_max: f64) -> bool {
        let mut t0 = 0.0f64;
        let mut t1 = t_max;
        for a in 0..3 {
            let ta = (self.min[a] - origin[a]) * inv_dir[a];
            let tb = (self.max[a] - origin[a]) * inv_dir[a];
            let (lo, hi) = if ta < tb { (ta, tb) } else { (tb, ta) };
            t0 = if lo > t0 { lo } else { t0 };
            t1 = if hi < t1 { hi } else { t1 };
            if t0 > t1 * (1.0 + 1e-12) {
                return false;
            }
        }
        true
    }
}

/// A geometric primitive.
#[derive(Debug, Clone)]
pub enum Shape {
    /// A sphere.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius (positive).
        radius: f64,
    },
    /// A triangle with optional per-vertex shading normals and texture coordinates.
    Triangle {
        /// Vertices.
        p: [Vec3; 3],
        /// Per-vertex shading normals.
        n: Option<[Vec3; 3]>,
        /// Per-vertex texture coordinates.
        uv: [[f64; 2]; 3],
    },
}

/// A BVH hit: shape index, ray parameter `t` and barycentric coordinates.
pub type BvhHit = (usize, f64, [f64; 2]);

impl Shape {
    /// Bounding box.
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::empty();
        match self {
            Shape::Sphere { center, radius } => {
                b.grow(&(center - Vec3::repeat(*radius)));
                b.grow(&(center + Vec3::repeat(*radius)));
            }
            Shape::Triangle { p, .. } => {
                for v in p {
                    b.grow(v);
                }
            }
        }
        b
    }

    /// Nearest intersection parameter in `(t_min, t_max)`, with barycentrics for triangles.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<(f64, [f64; 2])> {
        match self {
            Shape::Sphere { center, radius } => {
                let oc = ray.origin - center;
                let b = oc.dot(&ray.direction);
                // robust discriminant: |oc - b d|² is the squared distance to the axis
                let perp = oc - ray.direction * b;
                let disc = radius * radius - perp.norm_squared();
                if disc < 0.0 {
                    return None;
                }
                let c = oc.norm_squared() - radius * radius;
                let sq = disc.sqrt();
                let q = if b > 0.0 { -b - sq } else { -b + sq };
                let (mut t0, mut t1) = (q, if q != 0.0 { c / q } else { 0.0 });
                if t0 > t1 {
                    std::mem::swap(&mut t0, &mut t1);
                }
                if t0 > t_min && t0 < t_max {
                    Some((t0, [0.0; 2]))
                } else if t1 > t_min && t1 < t_max {
                    Some((t1, [0.0; 2]))
                } else {
                    None
                }
            }
            Shape::Triangle { p, .. } => {
                let e1 = p[1] - p[0];
                let e2 = p[2] - p[0];
                let pv = ray.direction.cross(&e2);
                let det = e1.dot(&pv);
                if det.abs() < 1e-300 {
                    return None;
                }
                let inv = 1.0 / det;
                let tv = ray.origin - p[0];
                let u = tv.dot(&pv) * inv;
                if !(0.0..=1.0).contains(&u) {
                    return None;
                }
                let qv = tv.cross(&e1);
                let v = ray.direction.dot(&qv) * inv;
                if v < 0.0 || u + v > 1.0 {
                    return None;
                }
                let t = e2.dot(&qv) * inv;
                (t > t_min && t < t_max).then_some((t, [u, v]))
            }
        }
    }

    /// Geometric normal, shading normal and texture coordinates at a hit.
    pub fn surface(&self, point: &Vec3, bary: [f64; 2]) -> (Vec3, Vec3, [f64; 2]) {
        match self {
            Shape::Sphere { center, radius } => {
                let n = (point - center) / *radius;
                let n = n.normalize();
                let u = 0.5 + n.z.atan2(n.x) / std::f64::consts::TAU;
                let v = n.y.clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
                (n, n, [u, v])
            }
            Shape::Triangle { p, n, uv } => {
                let ng = (p[1] - p[0]).cross(&(p[2] - p[0])).normalize();
                let [b1, b2] = bary;
                let b0 = 1.0 - b1 - b2;
                let ns = match n {
                    Some(n) => {
                        let s = n[0] * b0 + n[1] * b1 + n[2] * b2;
                        let len = s.norm();
                        if len > 1e-12 {
                            let s = s / len;
                            if s.dot(&ng) < 0.0 {
                                -s
                            } else {
                                s
                            }
                        } else {
                            ng
                        }
                    }
                    None => ng,
                };
                let t = [
                    uv[0][0] * b0 + uv[1][0] * b1 + uv[2][0] * b2,
                    uv[0][1] * b0 + uv[1][1] * b1 + uv[2][1] * b2,
                ];
                (ng, ns, t)
            }
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Node {
    bounds: Aabb,
    /// Leaf: first primitive index; interior: index of the second child.
    offset: u32,
    /// Number of primitives (0 for interior nodes).
    count: u32,
    axis: u8,
}

/// Bounding volume hierarchy over shapes (binned surface-area heuristic).
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    /// Shape indices in leaf order.
    order: Vec<u32>,
}

const BINS: usize = 16;
const LEAF_SIZE: usize = 4;

impl Bvh {
    /// Builds the hierarchy over `shapes`.
    pub fn build(shapes: &[Shape]) -> Self {
        let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
        let centroids: Vec<Vec3> = bounds.iter().map(Aabb::centroid).collect();
        let mut order: Vec<u32> = (0..shapes.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * shapes.len().max(1));
        if !shapes.is_empty() {
            build_node(&bounds, &centroids, &mut order, 0, shapes.len(), &mut nodes);
        }
        Self { nodes, order }
    }

    /// Nearest hit: (shape index, t, barycentrics).
    pub fn intersect(&self, shapes: &[Shape], ray: &Ray, t_min: f64, t_max: f64) -> Option<BvhHit> {
        self.traverse::<false>(shapes, ray, t_min, t_max)
    }

    /// Whether anything is hit in `(t_min, t_max)`.
    pub fn occluded(&self, shapes: &[Shape], ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.traverse::<true>(shapes, ray, t_min, t_max).is_some()
    }

    /// Front-to-back traversal. With `ANY_HIT` it returns the first hit found; otherwise it
    /// shrinks the interval to each hit and returns the nearest. The flag is a constant, so
    /// each use compiles to its own loop.
    #[inline(always)]
    fn traverse<const ANY_HIT: bool>(
        &self,
        shapes: &[Shape],
        ray: &Ray,
        t_min: f64,
        t_max: f64,
    ) -> Option<BvhHit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = Vec3::new(
            1.0 / ray.direction.x,
            1.0 / ray.direction.y,
            1.0 / ray.direction.z,
        );
        let neg = [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0];
        let mut best: Option<(usize, f64, [f64; 2])> = None;
        let mut t_best = t_max;
        let mut stack = [0usize; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let ni = stack[sp];
            let node = &self.nodes[ni];
            if !node.bounds.hit(&ray.origin, &inv, t_best) {
                continue;
            }
            if node.count > 0 {
                let s = node.offset as usize;
                for &idx in &self.order[s..s + node.count as usize] {
                    if let Some((t, b)) = shapes[idx as usize].intersect(ray, t_min, t_best) {
                        best = Some((idx as usize, t, b));
                        if ANY_HIT {
                            return best;
                        }
                        t_best = t;
                    }
                }
            } else if sp + 2 <= stack.len() {
                let (first, second) = if neg[node.axis as usize] {
                    (node.offset as usize, ni + 1)
                } else {
                    (ni + 1, node.offset as usize)
                };
                stack[sp] = second;
                stack[sp + 1] = first;
                sp += 2;
            }
        }
        best
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
}

fn build_node(
    bounds: &[Aabb],
    centroids: &[Vec3],
    order: &mut [u32],
    start: usize,
    end: usize,
    nodes: &mut Vec<Node>,
) -> usize {
    let me = nodes.len();
    let mut bb = Aabb::empty();
    let mut cb = Aabb::empty();
    for &i in &order[start..end] {
        bb = bb.union(&bounds[i as usize]);
        cb.grow(&centroids[i as usize]);
    }
    nodes.push(Node {
        bounds: bb,
        offset: start as u32,
        count: (end - start) as u32,
        axis: 0,
    });
    let n = end - start;
    if n <= LEAF_SIZE {
        return me;
    }
    let extent = cb.max - cb.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    if extent[axis] <= 0.0 {
        return me;
    }
    // binned SAH
    let mut bin_bounds = [Aabb::empty(); BINS];
    let mut bin_count = [0usize; BINS];
    let bin_of = |c: &Vec3| -> usize {
        (((c[axis] - cb.min[axis]) / extent[axis] * BINS as f64) as usize).min(BINS - 1)
    };
    for &i in &order[start..end] {
        let b = bin_of(&centroids[i as usize]);
        bin_count[b] += 1;
        bin_bounds[b] = bin_bounds[b].union(&bounds[i as usize]);
    }
    let mut best_cost = f64::INFINITY;
    let mut best_split = 0;
    for split in 1..BINS {
        let (mut lb, mut rb) = (Aabb::empty(), Aabb::empty());
        let (mut lc, mut rc) = (0usize, 0usize);
        for b in 0..split {
            lb = lb.union(&bin_bounds[b]);
            lc += bin_count[b];
        }
        for b in split..BINS {
            rb = rb.union(&bin_bounds[b]);
            rc += bin_count[b];
        }
        if lc == 0 || rc == 0 {
            continue;
        }
        let cost = lb.area() * lc as f64 + rb.area() * rc as f64;
        if cost < best_cost {
            best_cost = cost;
            best_split = split;
        }
    }
    let mid = if best_split == 0 {
        // all centroids in one bin: median split
        let slice = &mut order[start..end];
        slice.sort_by(|a, b| centroids[*a as usize][axis].total_cmp(&centroids[*b as usize][axis]));
        start + n / 2
    } else {
        let slice = &mut order[start..end];
        let mut i = 0;
        for j in 0..slice.len() {
            if bin_of(&centroids[slice[j] as usize]) < best_split {
                slice.swap(i, j);
                i += 1;
            }
        }
        start + i
    };
    if mid == start || mid == end {
        return me;
    }
    build_node(bounds, centroids, order, start, mid, nodes);
    let right = build_node(bounds, centroids, order, mid, end, nodes);
    nodes[me].offset = right as u32;
    nodes[me].count = 0;
    nodes[me].axis = axis as u8;
    me
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn bvh_agrees_with_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut shapes = Vec::new();
        for i in 0..300 {
            let c = Vec3::new(
                rng.gen_range(-5.0..5.0),
                rng.gen_range(-5.0..5.0),
                rng.gen_range(-5.0..5.0),
            );
            if i % 2 == 0 {
                shapes.push(Shape::Sphere {
                    center: c,
                    radius: rng.gen_range(0.05..0.4),
                });
            } else {
                let d = || Vec3::new(0.0, 0.0, 0.0);
                let _ = d;
                let p = [
                    c,
                    c + Vec3::new(
                        rng.gen_range(-0.5..0.5),
                        rng.gen_range(-0.5..0.5),
                        rng.gen_range(-0.5..0.5),
                    ),
                    c + Vec3::new(
                        rng.gen_range(-0.5..0.5),
                        rng.gen_range(-0.5..0.5),
                        rng.gen_range(-0.5..0.5),
                    ),
                ];
                shapes.push(Shape::Triangle {
                    p,
                    n: None,
                    uv: [[0.0; 2]; 3],
                });
            }
        }
        let bvh = Bvh::build(&shapes);
        for _ in 0..2000 {
            let o = Vec3::new(
                rng.gen_range(-8.0..8.0),
                rng.gen_range(-8.0..8.0),
                rng.gen_range(-8.0..8.0),
            );
            let d = Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            )
            .normalize();
            let ray = Ray::new(o, d);
            let brute = shapes
                .iter()
                .enumerate()
                .filter_map(|(i, s)| s.intersect(&ray, 1e-9, f64::INFINITY).map(|h| (i, h.0)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let fast = bvh.intersect(&shapes, &ray, 1e-9, f64::INFINITY);
            match (brute, fast) {
                (None, None) => {}
                (Some((_, tb)), Some((_, tf, _))) => assert!((tb - tf).abs() < 1e-9),
                other => panic!("mismatch {other:?}"),
            }
            assert_eq!(
                brute.is_some(),
                bvh.occluded(&shapes, &ray, 1e-9, f64::INFINITY)
            );
        }
    }
}
