//! A bounding volume hierarchy over triangles, built with the surface area
//! heuristic on binned centroids, and traversed front to back.

use crate::math::{Aabb, Ray, Vec3};

/// A triangle ready for intersection: one corner and two edges.
#[derive(Clone, Copy, Debug)]
pub struct Triangle {
    /// First corner.
    pub v0: Vec3,
    /// Second corner minus the first.
    pub e1: Vec3,
    /// Third corner minus the first.
    pub e2: Vec3,
}

impl Triangle {
    /// From three corners.
    pub fn new(a: Vec3, b: Vec3, c: Vec3) -> Self {
        Triangle {
            v0: a,
            e1: b - a,
            e2: c - a,
        }
    }

    /// The bounding box.
    pub fn bounds(&self) -> Aabb {
        Aabb::EMPTY
            .grow(self.v0)
            .grow(self.v0 + self.e1)
            .grow(self.v0 + self.e2)
    }

    /// Möller–Trumbore: the distance and barycentrics (b1, b2) of the hit
    /// with `ray` in `(t_min, t_max)`, from either side.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        let p = ray.dir.cross(self.e2);
        let det = self.e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let inv = 1.0 / det;
        let s = ray.origin - self.v0;
        let b1 = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let q = s.cross(self.e1);
        let b2 = ray.dir.dot(q) * inv;
        if b2 < 0.0 || b1 + b2 > 1.0 {
            return None;
        }
        let t = self.e2.dot(q) * inv;
        (t > t_min && t < t_max).then_some((t, b1, b2))
    }
}

/// The closest hit of a ray: distance, triangle (index in the caller's
/// order) and barycentrics of the second and third corners.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray (in units of its direction's length).
    pub t: f32,
    /// The triangle's index as given to [`Bvh::build`].
    pub triangle: u32,
    /// Barycentric weight of the second corner.
    pub b1: f32,
    /// Barycentric weight of the third corner.
    pub b2: f32,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Interior: index of the left child (the right one follows it).
    /// Leaf: first entry in `order`.
    first: u32,
    /// Triangles in a leaf; 0 for interior nodes.
    count: u32,
}

/// The hierarchy: nodes in depth-first order and the triangles reordered
/// so each leaf's are contiguous.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node>,
    triangles: Vec<Triangle>,
    /// Original index of each reordered triangle.
    order: Vec<u32>,
}

const BINS: usize = 16;
const MAX_LEAF: usize = 4;
/// Cost of a ray-box test relative to a ray-triangle test.
const TRAVERSAL_COST: f32 = 1.0;

impl Bvh {
    /// Builds the hierarchy over `triangles`.
    pub fn build(triangles: &[Triangle]) -> Bvh {
        let boxes: Vec<Aabb> = triangles.iter().map(Triangle::bounds).collect();
        let centres: Vec<Vec3> = boxes.iter().map(|b| b.centre()).collect();
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let mut nodes = vec![Node {
            bounds: Aabb::EMPTY,
            first: 0,
            count: 0,
        }];
        if !triangles.is_empty() {
            build_node(&mut nodes, 0, &mut order, 0, &boxes, &centres);
        }
        Bvh {
            triangles: order.iter().map(|&i| triangles[i as usize]).collect(),
            nodes,
            order,
        }
    }

    /// The closest hit in `(t_min, t_max)`.
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_far = t_max;
        self.traverse(ray, t_max, |i, tri| {
            if let Some((t, b1, b2)) = tri.intersect(ray, t_min, t_far) {
                t_far = t;
                best = Some(Hit {
                    t,
                    triangle: i,
                    b1,
                    b2,
                });
            }
            (false, t_far)
        });
        best
    }

    /// Whether anything lies on the ray within `(t_min, t_max)` (for shadows).
    pub fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        let mut hit = false;
        self.traverse(ray, t_max, |_, tri| {
            hit = tri.intersect(ray, t_min, t_max).is_some();
            (hit, t_max)
        });
        hit
    }

    /// Visits candidate triangles front to back; `visit` returns whether to
    /// stop and the current far limit.
    fn traverse(
        &self,
        ray: &Ray,
        t_max: f32,
        mut visit: impl FnMut(u32, &Triangle) -> (bool, f32),
    ) {
        if self.triangles.is_empty() {
            return;
        }
        let inv = Vec3::new(1.0 / ray.dir.x, 1.0 / ray.dir.y, 1.0 / ray.dir.z);
        let mut t_far = t_max;
        if self.nodes[0].bounds.hit(ray.origin, inv, t_far).is_none() {
            return;
        }
        // Nodes to visit with the distance where the ray enters them: a node
        // entered beyond the closest hit found since it was pushed is skipped.
        let mut stack = [(0u32, 0f32); 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (index, entry) = stack[top];
            if entry > t_far {
                continue;
            }
            let node = &self.nodes[index as usize];
            if node.count > 0 {
                let start = node.first as usize;
                for k in start..start + node.count as usize {
                    let (stop, far) = visit(self.order[k], &self.triangles[k]);
                    if stop {
                        return;
                    }
                    t_far = far;
                }
                continue;
            }
            let (l, r) = (node.first, node.first + 1);
            let tl = self.nodes[l as usize].bounds.hit(ray.origin, inv, t_far);
            let tr = self.nodes[r as usize].bounds.hit(ray.origin, inv, t_far);
            // Push the far child first so the near one is visited next.
            match (tl, tr) {
                (Some(a), Some(b)) => {
                    let (near, far) = if a <= b {
                        ((l, a), (r, b))
                    } else {
                        ((r, b), (l, a))
                    };
                    stack[top] = far;
                    stack[top + 1] = near;
                    top += 2;
                }
                (Some(a), None) => {
                    stack[top] = (l, a);
                    top += 1;
                }
                (None, Some(b)) => {
                    stack[top] = (r, b);
                    top += 1;
                }
                (None, None) => {}
            }
        }
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The bounds of everything.
    pub fn bounds(&self) -> Aabb {
        self.nodes[0].bounds
    }

    /// The depth of the deepest leaf (the root is depth 1).
    pub fn depth(&self) -> usize {
        fn depth(nodes: &[Node], i: usize) -> usize {
            let n = &nodes[i];
            if n.count > 0 {
                1
            } else {
                1 + depth(nodes, n.first as usize).max(depth(nodes, n.first as usize + 1))
            }
        }
        depth(&self.nodes, 0)
    }
}

/// Fills node `index` with `items` (a slice of `order` starting at `offset`),
/// splitting where the binned SAH says it pays.
fn build_node(
    nodes: &mut Vec<Node>,
    index: usize,
    items: &mut [u32],
    offset: usize,
    boxes: &[Aabb],
    centres: &[Vec3],
) {
    let bounds = items
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.union(boxes[i as usize]));
    let make_leaf = |nodes: &mut Vec<Node>| {
        nodes[index] = Node {
            bounds,
            first: offset as u32,
            count: items.len() as u32,
        };
    };
    if items.len() <= 1 {
        return make_leaf(nodes);
    }
    let split = best_split(items, boxes, centres, bounds);
    let mid = match split {
        Some((axis, plane, cost)) if items.len() > MAX_LEAF || cost < items.len() as f32 => {
            let mid = partition(items, |&i| centres[i as usize][axis] < plane);
            if mid == 0 || mid == items.len() {
                items.len() / 2
            } else {
                mid
            }
        }
        _ if items.len() > MAX_LEAF => {
            // All centres in one place: split the list in half.
            items.len() / 2
        }
        _ => return make_leaf(nodes),
    };
    let left = nodes.len();
    nodes.push(Node {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
    });
    nodes.push(Node {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
    });
    nodes[index] = Node {
        bounds,
        first: left as u32,
        count: 0,
    };
    let (a, b) = items.split_at_mut(mid);
    build_node(nodes, left, a, offset, boxes, centres);
    build_node(nodes, left + 1, b, offset + mid, boxes, centres);
}

/// The best (axis, plane, relative cost) over `BINS` bins per axis; cost is
/// in triangle-test units, comparable to the leaf's `items.len()`.
fn best_split(
    items: &[u32],
    boxes: &[Aabb],
    centres: &[Vec3],
    bounds: Aabb,
) -> Option<(usize, f32, f32)> {
    let cb = items
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.grow(centres[i as usize]));
    let area = bounds.area().max(1e-30);
    let mut best: Option<(usize, f32, f32)> = None;
    for axis in [0usize, 1, 2] {
        let (lo, hi) = (cb.min[axis], cb.max[axis]);
        if hi - lo <= 1e-12 * (1.0 + lo.abs()) {
            continue;
        }
        let scale = BINS as f32 / (hi - lo);
        let mut bin_box = [Aabb::EMPTY; BINS];
        let mut bin_count = [0usize; BINS];
        for &i in items {
            let b = (((centres[i as usize][axis] - lo) * scale) as usize).min(BINS - 1);
            bin_box[b] = bin_box[b].union(boxes[i as usize]);
            bin_count[b] += 1;
        }
        // Sweep from the right to get each suffix's area and count.
        let mut right_area = [0f32; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(bin_box[b]);
            n += bin_count[b];
            right_area[b] = acc.area();
            right_count[b] = n;
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in 1..BINS {
            acc = acc.union(bin_box[b - 1]);
            n += bin_count[b - 1];
            if n == 0 || right_count[b] == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (acc.area() * n as f32 + right_area[b] * right_count[b] as f32) / area;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((axis, lo + b as f32 / scale, cost));
            }
        }
    }
    best
}

/// Moves the items where `left` holds to the front; returns how many.
fn partition(items: &mut [u32], left: impl Fn(&u32) -> bool) -> usize {
    let mut mid = 0;
    for k in 0..items.len() {
        if left(&items[k]) {
            items.swap(k, mid);
            mid += 1;
        }
    }
    mid
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{uniform_sphere, Pcg32};

    fn random_triangles(rng: &mut Pcg32, n: usize) -> Vec<Triangle> {
        (0..n)
            .map(|_| {
                let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                let mut corner = || {
                    c + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5)
                };
                Triangle::new(corner(), corner(), corner())
            })
            .collect()
    }

    fn brute_force(tris: &[Triangle], ray: &Ray) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for (i, tri) in tris.iter().enumerate() {
            if let Some((t, _, _)) = tri.intersect(ray, 1e-4, f32::INFINITY) {
                if best.is_none_or(|(bt, _)| t < bt) {
                    best = Some((t, i as u32));
                }
            }
        }
        best
    }

    #[test]
    fn closest_hits_and_shadows_match_brute_force() {
        let mut rng = Pcg32::new(11, 0);
        for n in [1, 3, 50, 2000] {
            let tris = random_triangles(&mut rng, n);
            let bvh = Bvh::build(&tris);
            assert_eq!(bvh.len(), n);
            let mut hits = 0;
            for _ in 0..2000 {
                let origin = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0
                    - Vec3::splat(2.0);
                let ray = Ray {
                    origin,
                    dir: uniform_sphere(rng.next_2d()),
                };
                let expected = brute_force(&tris, &ray);
                let got = bvh.intersect(&ray, 1e-4, f32::INFINITY);
                assert_eq!(got.map(|h| (h.t, h.triangle)), expected, "{n} triangles");
                let limit = 3.0;
                assert_eq!(
                    bvh.occluded(&ray, 1e-4, limit),
                    expected.is_some_and(|(t, _)| t < limit)
                );
                hits += expected.is_some() as usize;
            }
            assert!(n < 2000 || hits > 200, "the test should hit often: {hits}");
        }
    }

    #[test]
    fn sah_keeps_the_tree_shallow_and_barycentrics_reconstruct_the_point() {
        let mut rng = Pcg32::new(2, 0);
        let tris = random_triangles(&mut rng, 4096);
        let bvh = Bvh::build(&tris);
        assert!(bvh.depth() < 40, "depth {}", bvh.depth());
        let ray = Ray {
            origin: Vec3::new(5.0, 5.0, -20.0),
            dir: Vec3::Z,
        };
        let h = bvh
            .intersect(&ray, 0.0, f32::INFINITY)
            .expect("the cloud is hit");
        let tri = &tris[h.triangle as usize];
        let p = tri.v0 + tri.e1 * h.b1 + tri.e2 * h.b2;
        assert!((p - ray.at(h.t)).length() < 1e-3);
    }
}
