//! Procedural scenes with a target triangle count (the polygon-count sweep axis), deterministic
//! from a seed. Every generator returns a complete scene: objects, a default camera looking at
//! the shadow, and a default light.
//!
//! Conventions: y is up, the ground is the plane y = 0, one unit is about one metre.

use glam::{Mat4, Vec3};

use super::light::Light;
use super::mesh::{Mesh, Object, Role};
use super::{Camera, Scene};
use crate::util::hash::{mix64, unit_f32};

/// Parameters every generator understands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeneratorParams {
    /// Target number of triangles of the whole scene; the generator gets within a few percent.
    pub triangles: Option<u32>,
    pub seed: u64,
    /// Height of the main occluder's lowest point above the receiver (contact-hardening sweeps).
    pub occluder_height: Option<f32>,
    /// Lateral offset of the moving occluders along world x (the u axis of the rectangular
    /// lights), in scene units, from the generator's own placement; the light and the receiver
    /// stay put (paper 002 §5.2.5). Only generators with [`Generator::moves_laterally`] apply it.
    pub occluder_offset: Option<f32>,
}

impl Default for GeneratorParams {
    fn default() -> Self {
        GeneratorParams {
            triangles: None,
            seed: 1,
            occluder_height: None,
            occluder_offset: None,
        }
    }
}

/// A named scene generator.
pub struct Generator {
    pub name: &'static str,
    pub summary: &'static str,
    pub default_triangles: u32,
    /// Whether the generator places an occluder at `occluder_height` above its ground. Street
    /// and fern, whose occluders stand on the ground, do not.
    pub moves_vertically: bool,
    /// Whether the generator has a moving occluder (the objects `occluder_height` places) that
    /// `occluder_offset` translates sideways. Scenes whose occluders are the whole set (room,
    /// street, fern) do not.
    pub moves_laterally: bool,
    build: fn(&GeneratorParams, u32) -> Scene,
}

impl Generator {
    pub fn build(&self, p: &GeneratorParams) -> Scene {
        let target = p.triangles.unwrap_or(self.default_triangles).max(1);
        let mut s = (self.build)(p, target);
        s.name = self.name.to_string();
        // As a mesh file's triangles are (`load::load_mesh`): no triangle without area (the
        // fern's leaf tips made 380) and no exact duplicate, so a generated scene and its
        // export describe the same triangles.
        for o in &mut s.objects {
            o.mesh.drop_degenerate();
        }
        s
    }
}

pub const GENERATORS: &[Generator] = &[
    Generator {
        name: "sphere-on-plane",
        summary: "UV sphere above a tessellated ground plane, sphere light",
        default_triangles: 2_000,
        moves_vertically: true,
        moves_laterally: true,
        build: sphere_on_plane,
    },
    Generator {
        name: "blob-on-plane",
        summary: "lumpy closed blob (a bunny stand-in) above the ground, sphere light (paper 000)",
        default_triangles: 10_000,
        moves_vertically: true,
        moves_laterally: true,
        build: blob_on_plane,
    },
    Generator {
        name: "plate-on-plane",
        summary: "thin square plate parallel to the ground, square light (paper 002)",
        default_triangles: 200,
        moves_vertically: true,
        moves_laterally: true,
        build: plate_on_plane,
    },
    Generator {
        name: "box-on-plane",
        summary: "tessellated box above the ground",
        default_triangles: 1_000,
        moves_vertically: true,
        moves_laterally: true,
        build: box_on_plane,
    },
    Generator {
        name: "cylinder-on-plane",
        summary: "upright capped cylinder on the ground (paper 001)",
        default_triangles: 1_000,
        moves_vertically: true,
        moves_laterally: true,
        build: cylinder_on_plane,
    },
    Generator {
        name: "torus-on-plane",
        summary: "tilted torus above the ground; many silhouette edges, holes",
        default_triangles: 2_000,
        moves_vertically: true,
        moves_laterally: true,
        build: torus_on_plane,
    },
    Generator {
        name: "sphere-grid",
        summary: "k x k x k grid of spheres (3x3x3 in paper 001) above the ground",
        default_triangles: 5_000,
        moves_vertically: true,
        moves_laterally: true,
        build: sphere_grid,
    },
    Generator {
        name: "replicated",
        summary: "K copies of a compound object (torus, box, sphere) for polygon sweeps",
        default_triangles: 10_000,
        moves_vertically: true,
        moves_laterally: true,
        build: replicated,
    },
    Generator {
        name: "terrain",
        summary: "fractal terrain receiver with floating occluders",
        default_triangles: 20_000,
        moves_vertically: true,
        moves_laterally: true,
        build: terrain,
    },
    Generator {
        name: "room",
        summary:
            "interior: walls, tables, chairs, objects; light near the ceiling (paper 004 saloon)",
        default_triangles: 20_000,
        moves_vertically: true,
        moves_laterally: false,
        build: room,
    },
    Generator {
        name: "street",
        summary: "exterior: buildings and posts, distant high light, many silhouette edges",
        default_triangles: 30_000,
        moves_vertically: false,
        moves_laterally: false,
        build: street,
    },
    Generator {
        name: "fern",
        summary: "fern: fronds of open leaflets over tessellated ground (paper 004 fern)",
        default_triangles: 20_000,
        moves_vertically: false,
        moves_laterally: false,
        build: fern,
    },
];

pub fn find(name: &str) -> Option<&'static Generator> {
    GENERATORS.iter().find(|g| g.name == name)
}

pub fn names() -> Vec<&'static str> {
    GENERATORS.iter().map(|g| g.name).collect()
}

fn object(name: &str, mesh: Mesh, role: Role) -> Object {
    Object {
        name: name.to_string(),
        mesh,
        role,
    }
}

fn ground(half: f32, triangles: u32) -> Object {
    let n = ((triangles as f32 / 2.0).sqrt().round() as u32).max(1);
    object("ground", primitives::plane(half, n), Role::RECEIVER)
}

/// `at` moved by the lateral occluder offset (unchanged when there is none, so scenes without
/// an offset keep their exact geometry).
fn lateral(p: &GeneratorParams, at: Vec3) -> Vec3 {
    match p.occluder_offset {
        Some(d) => at + Vec3::X * d,
        None => at,
    }
}

fn sphere_on_plane(p: &GeneratorParams, target: u32) -> Scene {
    let h = p.occluder_height.unwrap_or(1.0);
    let ground_tris = (target / 10).clamp(2, 2_000);
    let sphere = primitives::uv_sphere_with_triangles(target.saturating_sub(ground_tris).max(8));
    let sphere = sphere.transformed(Mat4::from_translation(lateral(
        p,
        Vec3::new(0.0, h + 1.0, 0.0),
    )));
    Scene::new(
        vec![
            ground(6.0, ground_tris),
            object("sphere", sphere, Role::BOTH),
        ],
        Camera::looking_at(Vec3::new(0.0, 4.5, 5.5), Vec3::new(-0.3, 0.8, 0.0), 45.0),
        Light::Sphere {
            center: Vec3::new(1.0, 8.0, 0.5),
            radius: 0.6,
        },
    )
}

/// A bunny-sized lumpy blob: a UV sphere displaced along its radius by a few smooth lobes
/// (phases from the seed), so its silhouette has concavities and vertices where more than two
/// silhouette edges meet, as the models of paper 000 do. Its lowest point is at the occluder
/// height.
fn blob_on_plane(p: &GeneratorParams, target: u32) -> Scene {
    let h = p.occluder_height.unwrap_or(0.4);
    let ground_tris = (target / 10).clamp(2, 2_000);
    let phase = |k: u64| unit_f32(mix64(p.seed ^ mix64(k))) * std::f32::consts::TAU;
    let (p1, p2, p3) = (phase(1), phase(2), phase(3));
    let mut blob = primitives::uv_sphere_with_triangles(target.saturating_sub(ground_tris).max(8));
    for v in &mut blob.positions {
        let d = *v;
        let lumps = 0.18 * (3.0 * d.x + p1).sin() * (2.0 * d.y + p2).cos()
            + 0.12 * (4.0 * d.z + p3).sin() * (3.0 * d.x - p1).cos()
            + 0.08 * (6.0 * d.y + p2 + p3).sin();
        *v = d * Vec3::new(1.0, 0.8, 0.9) * (1.0 + lumps);
    }
    let lowest = blob
        .positions
        .iter()
        .map(|v| v.y)
        .fold(f32::INFINITY, f32::min);
    let blob = blob.transformed(Mat4::from_translation(lateral(
        p,
        Vec3::new(0.0, h - lowest, 0.0),
    )));
    Scene::new(
        vec![ground(6.0, ground_tris), object("blob", blob, Role::BOTH)],
        Camera::looking_at(Vec3::new(0.0, 4.5, 6.0), Vec3::new(-0.8, 0.6, -0.5), 45.0),
        Light::Sphere {
            center: Vec3::new(1.5, 7.0, 1.5),
            radius: 0.5,
        },
    )
}

fn plate_on_plane(p: &GeneratorParams, target: u32) -> Scene {
    let h = p.occluder_height.unwrap_or(1.5);
    let ground_tris = (target / 2).clamp(2, 2_000);
    let plate = primitives::cuboid(
        lateral(p, Vec3::new(-1.0, h, -1.0)),
        lateral(p, Vec3::new(1.0, h + 0.02, 1.0)),
    );
    Scene::new(
        vec![ground(5.0, ground_tris), object("plate", plate, Role::BOTH)],
        Camera::looking_at(Vec3::new(0.0, 7.0, 6.0), Vec3::new(0.0, 0.0, 0.0), 45.0),
        Light::Rect {
            center: Vec3::new(0.0, 6.0, 0.0),
            half_u: Vec3::new(0.5, 0.0, 0.0),
            half_v: Vec3::new(0.0, 0.0, 0.5),
        },
    )
}

fn default_view() -> Camera {
    Camera::looking_at(Vec3::new(0.0, 6.0, 8.0), Vec3::new(0.0, 0.5, 0.0), 45.0)
}

fn box_on_plane(p: &GeneratorParams, target: u32) -> Scene {
    let h = p.occluder_height.unwrap_or(0.8);
    let ground_tris = (target / 10).clamp(2, 2_000);
    let per_face = (target.saturating_sub(ground_tris) / 12).max(1);
    let n = ((per_face as f32).sqrt().round() as u32).max(1);
    let b = primitives::tessellated_cuboid(
        lateral(p, Vec3::new(-0.8, h, -0.8)),
        lateral(p, Vec3::new(0.8, h + 1.2, 0.8)),
        n,
    );
    Scene::new(
        vec![ground(6.0, ground_tris), object("box", b, Role::BOTH)],
        default_view(),
        Light::Sphere {
            center: Vec3::new(1.5, 8.0, 1.0),
            radius: 0.6,
        },
    )
}

fn cylinder_on_plane(p: &GeneratorParams, target: u32) -> Scene {
    let h = p.occluder_height.unwrap_or(0.0);
    let ground_tris = (target / 10).clamp(2, 2_000);
    let c = primitives::cylinder_with_triangles(0.6, 2.5, target.saturating_sub(ground_tris))
        .transformed(Mat4::from_translation(lateral(p, Vec3::new(0.0, h, 0.0))));
    Scene::new(
        vec![ground(6.0, ground_tris), object("cylinder", c, Role::BOTH)],
        default_view(),
        Light::Rect {
            center: Vec3::new(2.0, 7.0, 1.0),
            half_u: Vec3::new(0.6, 0.0, 0.0),
            half_v: Vec3::new(0.0, 0.0, 0.6),
        },
    )
}

fn torus_on_plane(p: &GeneratorParams, target: u32) -> Scene {
    let h = p.occluder_height.unwrap_or(1.0);
    let ground_tris = (target / 10).clamp(2, 2_000);
    let t = primitives::torus_with_triangles(1.2, 0.35, target.saturating_sub(ground_tris))
        .transformed(
            Mat4::from_translation(lateral(p, Vec3::new(0.0, h + 1.2, 0.0)))
                * Mat4::from_rotation_x(1.1),
        );
    Scene::new(
        vec![ground(6.0, ground_tris), object("torus", t, Role::BOTH)],
        default_view(),
        Light::Sphere {
            center: Vec3::new(0.5, 8.0, 0.5),
            radius: 0.6,
        },
    )
}

fn sphere_grid(p: &GeneratorParams, target: u32) -> Scene {
    let k = 3;
    let h = p.occluder_height.unwrap_or(0.5);
    let ground_tris = (target / 10).clamp(2, 2_000);
    let per_sphere = (target.saturating_sub(ground_tris) / (k * k * k)).max(8);
    let unit = primitives::uv_sphere_with_triangles(per_sphere);
    let mut objects = vec![ground(6.0, ground_tris)];
    for i in 0..k {
        for j in 0..k {
            for l in 0..k {
                let c = lateral(
                    p,
                    Vec3::new(
                        (i as f32 - 1.0) * 1.0,
                        h + 0.35 + j as f32 * 1.0,
                        (l as f32 - 1.0) * 1.0,
                    ),
                );
                let m = unit
                    .clone()
                    .transformed(Mat4::from_translation(c) * Mat4::from_scale(Vec3::splat(0.35)));
                objects.push(object(&format!("sphere{i}{j}{l}"), m, Role::BOTH));
            }
        }
    }
    Scene::new(
        objects,
        default_view(),
        Light::Rect {
            center: Vec3::new(1.0, 8.0, 0.5),
            half_u: Vec3::new(1.0, 0.0, 0.0),
            half_v: Vec3::new(0.0, 0.0, 1.0),
        },
    )
}

/// One compound object (torus through a box with a sphere on top), about `budget` triangles.
fn compound(budget: u32) -> Mesh {
    let mut m = primitives::torus_with_triangles(0.5, 0.12, budget / 2)
        .transformed(Mat4::from_rotation_x(std::f32::consts::FRAC_PI_2));
    m.append(&primitives::cuboid(
        Vec3::new(-0.2, -0.6, -0.2),
        Vec3::new(0.2, -0.2, 0.2),
    ));
    m.append(
        &primitives::uv_sphere_with_triangles(budget.saturating_sub(budget / 2 + 12).max(8))
            .transformed(
                Mat4::from_translation(Vec3::new(0.0, 0.75, 0.0))
                    * Mat4::from_scale(Vec3::splat(0.25)),
            ),
    );
    m
}

fn replicated(p: &GeneratorParams, target: u32) -> Scene {
    let h = p.occluder_height.unwrap_or(0.8);
    let ground_tris = (target / 20).clamp(2, 2_000);
    let budget = target.saturating_sub(ground_tris);
    // K copies of about 400 triangles each, so the polygon sweep grows the copy count.
    let copies = (budget / 400).max(1);
    let side = (copies as f32).sqrt().ceil() as u32;
    let per = (budget / copies).max(40);
    let unit = compound(per);
    let spacing = 5.0 / side as f32;
    let scale = spacing * 0.45;
    let mut objects = vec![ground(6.0, ground_tris)];
    for c in 0..copies {
        let (i, j) = (c % side, c / side);
        let jitter = unit_f32(mix64(p.seed ^ c as u64)) * std::f32::consts::TAU;
        let at = lateral(
            p,
            Vec3::new(
                (i as f32 + 0.5) * spacing - 2.5,
                h + 0.6 * scale,
                (j as f32 + 0.5) * spacing - 2.5,
            ),
        );
        let m = unit.clone().transformed(
            Mat4::from_translation(at)
                * Mat4::from_rotation_y(jitter)
                * Mat4::from_scale(Vec3::splat(scale)),
        );
        objects.push(object(&format!("copy{c}"), m, Role::BOTH));
    }
    Scene::new(
        objects,
        default_view(),
        Light::Rect {
            center: Vec3::new(0.5, 8.0, 0.5),
            half_u: Vec3::new(0.6, 0.0, 0.0),
            half_v: Vec3::new(0.0, 0.0, 0.6),
        },
    )
}

fn terrain(p: &GeneratorParams, target: u32) -> Scene {
    let h = p.occluder_height.unwrap_or(1.5);
    let occ_tris = (target / 5).max(16);
    let n = (((target.saturating_sub(occ_tris)) as f32 / 2.0)
        .sqrt()
        .round() as u32)
        .max(2);
    let ground = primitives::fractal_terrain(6.0, n, 0.6, p.seed);
    let mut objects = vec![object("terrain", ground, Role::BOTH)];
    for k in 0..4u32 {
        let a = k as f32 * std::f32::consts::FRAC_PI_2 + 0.4;
        let m = primitives::uv_sphere_with_triangles(occ_tris / 4).transformed(
            Mat4::from_translation(lateral(p, Vec3::new(2.0 * a.cos(), h + 0.6, 2.0 * a.sin())))
                * Mat4::from_scale(Vec3::splat(0.5)),
        );
        objects.push(object(&format!("rock{k}"), m, Role::BOTH));
    }
    Scene::new(
        objects,
        default_view(),
        Light::Sphere {
            center: Vec3::new(1.0, 9.0, -1.0),
            radius: 0.7,
        },
    )
}

/// Slices of a bottle in the room, and the share of the room's free triangle budget they take.
const BOTTLE_SLICES: u32 = 16;
const BOTTLE_SHARE_PERCENT: u32 = 40;

fn room(p: &GeneratorParams, target: u32) -> Scene {
    let (w, hgt, d) = (10.0, 4.0, 8.0);
    let table_h = p.occluder_height.unwrap_or(0.9);
    let mut objects = Vec::new();
    // Floor and walls face inwards (the room is seen from inside).
    let shell = primitives::tessellated_cuboid(
        Vec3::new(-w / 2.0, 0.0, -d / 2.0),
        Vec3::new(w / 2.0, hgt, d / 2.0),
        ((target as f32 / 40.0 / 12.0).sqrt().round() as u32).clamp(1, 40),
    );
    let shell = Mesh {
        triangles: shell.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect(),
        positions: shell.positions,
    };
    let shell_tris = shell.triangles.len() as u32;
    objects.push(object("shell", shell, Role::RECEIVER));
    let mut furniture = Mesh::default();
    let tables = [(-2.5, -1.0), (1.0, -1.5), (2.8, 1.2), (-1.5, 1.8)];
    let mut boxes = 0u32;
    for (k, &(x, z)) in tables.iter().enumerate() {
        let top = primitives::cuboid(
            Vec3::new(x - 0.8, table_h, z - 0.5),
            Vec3::new(x + 0.8, table_h + 0.06, z + 0.5),
        );
        furniture.append(&top);
        for (lx, lz) in [(-0.7, -0.4), (0.7, -0.4), (-0.7, 0.4), (0.7, 0.4)] {
            furniture.append(&primitives::cuboid(
                Vec3::new(x + lx - 0.04, 0.0, z + lz - 0.04),
                Vec3::new(x + lx + 0.04, table_h, z + lz + 0.04),
            ));
        }
        // A chair beside each table: seat, back, legs.
        let cz = z + 0.9 * if k % 2 == 0 { 1.0 } else { -1.0 };
        furniture.append(&primitives::cuboid(
            Vec3::new(x - 0.25, 0.45, cz - 0.25),
            Vec3::new(x + 0.25, 0.5, cz + 0.25),
        ));
        furniture.append(&primitives::cuboid(
            Vec3::new(x - 0.25, 0.5, cz + 0.2),
            Vec3::new(x + 0.25, 1.0, cz + 0.25),
        ));
        for (lx, lz) in [(-0.22, -0.22), (0.22, -0.22), (-0.22, 0.22), (0.22, 0.22)] {
            furniture.append(&primitives::cuboid(
                Vec3::new(x + lx - 0.025, 0.0, cz + lz - 0.025),
                Vec3::new(x + lx + 0.025, 0.45, cz + lz + 0.025),
            ));
        }
        boxes += 1 + 4 + 2 + 4;
    }
    // A bar counter along the back wall.
    furniture.append(&primitives::cuboid(
        Vec3::new(-4.0, 0.0, -3.6),
        Vec3::new(1.0, 1.1, -3.0),
    ));
    boxes += 1;
    objects.push(object("furniture", furniture, Role::BOTH));
    // The remaining budget: bottles on the bar and the tables (one-ring cylinders, many
    // silhouette edges per triangle) and lamps (spheres, few). The split gives about one
    // silhouette edge from the light per 7.5 triangles, as the saloon of paper 004 (Table 2:
    // 60K triangles, 8K silhouette edges).
    let rest = target.saturating_sub(shell_tris + boxes * 12);
    let bottle_tris = 4 * BOTTLE_SLICES;
    let bottles = (rest * BOTTLE_SHARE_PERCENT / 100 / bottle_tris).max(4);
    let mut shelf = Mesh::default();
    let surfaces: Vec<(f32, f32, f32, f32, f32)> = std::iter::once((-4.0, 1.0, -3.6, -3.0, 1.1))
        .chain(
            tables
                .iter()
                .map(|&(x, z)| (x - 0.8, x + 0.8, z - 0.5, z + 0.5, table_h + 0.06)),
        )
        .collect();
    let per_surface = bottles.div_ceil(surfaces.len() as u32);
    let cols = ((per_surface as f32 * 3.0).sqrt().ceil() as u32).max(1);
    let rows = per_surface.div_ceil(cols);
    for k in 0..bottles {
        let (x0, x1, z0, z1, y) = surfaces[(k % surfaces.len() as u32) as usize];
        let i = k / surfaces.len() as u32;
        let (cx, cz) = ((i % cols) as f32 + 0.5, (i / cols) as f32 + 0.5);
        let at = Vec3::new(
            x0 + (x1 - x0) * cx / cols as f32,
            y,
            z0 + (z1 - z0) * cz / rows as f32,
        );
        let r = 0.02 + 0.015 * unit_f32(mix64(p.seed ^ (1000 + k as u64)));
        shelf.append(
            &primitives::cylinder(r, 0.12 + 8.0 * r, BOTTLE_SLICES, 1)
                .transformed(Mat4::from_translation(at)),
        );
    }
    let shelf_tris = shelf.triangles.len() as u32;
    objects.push(object("bottles", shelf, Role::BOTH));
    let per_item = (rest.saturating_sub(shelf_tris) / 16).max(8);
    for (k, &(x, z)) in tables.iter().enumerate() {
        for q in 0..4u32 {
            let r = unit_f32(mix64(p.seed ^ (k as u64 * 16 + q as u64)));
            let at = Vec3::new(
                x - 0.5 + 0.33 * q as f32,
                table_h + 0.06 + 0.15,
                z - 0.2 + 0.4 * r,
            );
            let m = primitives::uv_sphere_with_triangles(per_item).transformed(
                Mat4::from_translation(at) * Mat4::from_scale(Vec3::new(0.1, 0.15, 0.1)),
            );
            objects.push(object(&format!("item{k}_{q}"), m, Role::BOTH));
        }
    }
    Scene::new(
        objects,
        Camera::looking_at(Vec3::new(-4.2, 2.6, 3.6), Vec3::new(1.0, 0.6, -1.0), 60.0),
        Light::Sphere {
            center: Vec3::new(0.0, 3.4, 0.0),
            radius: 0.25,
        },
    )
}

/// Share of the street's triangle budget in window ledges.
const LEDGE_SHARE_PERCENT: u32 = 26;

fn street(p: &GeneratorParams, target: u32) -> Scene {
    let ground_tris = (target / 20).clamp(2, 4_000);
    let mut objects = vec![ground(30.0, ground_tris)];
    let blocks = 6u32;
    let mut buildings = Mesh::default();
    let mut count = 0u32;
    for i in 0..blocks {
        for j in 0..blocks {
            if i == blocks / 2 || j == blocks / 2 {
                continue; // the street crossing
            }
            let r = unit_f32(mix64(p.seed ^ (i * 31 + j) as u64));
            let (x, z) = (i as f32 * 8.0 - 20.0, j as f32 * 8.0 - 20.0);
            let height = 4.0 + 14.0 * r;
            buildings.append(&primitives::cuboid(
                Vec3::new(x - 2.5, 0.0, z - 2.5),
                Vec3::new(x + 2.5, height, z + 2.5),
            ));
            // A roof box for a stepped silhouette.
            buildings.append(&primitives::cuboid(
                Vec3::new(x - 1.5, height, z - 1.5),
                Vec3::new(x + 1.0, height + 1.5, z + 1.0),
            ));
            count += 2;
        }
    }
    objects.push(object("buildings", buildings, Role::BOTH));
    // Window ledges on the facades: small boxes, about half of whose edges are silhouettes
    // from the high light; with the posts they give the street of paper 004 (Table 2: 155K
    // triangles, 29K silhouette edges).
    let ledges_wanted = target * LEDGE_SHARE_PERCENT / 100 / 12;
    let per_building = ledges_wanted / count.max(1) * 2;
    let mut ledges = Mesh::default();
    let mut k = 0u32;
    for i in 0..blocks {
        for j in 0..blocks {
            if i == blocks / 2 || j == blocks / 2 {
                continue;
            }
            let (x, z) = (i as f32 * 8.0 - 20.0, j as f32 * 8.0 - 20.0);
            let height = 4.0 + 14.0 * unit_f32(mix64(p.seed ^ (i * 31 + j) as u64));
            // Four facades, columns across, floors up.
            let cols = 6u32;
            let floors = (per_building / 4).div_ceil(cols).max(1);
            for n in 0..per_building {
                let face = n % 4;
                let m = n / 4;
                let (c, f) = (m % cols, m / cols);
                let s = -2.2 + 4.4 * (c as f32 + 0.5) / cols as f32;
                let y = 0.8 + (height - 1.0) * (f as f32 + 0.5) / floors as f32;
                let (lo, hi) = match face {
                    0 => (
                        Vec3::new(x + s - 0.25, y, z + 2.5),
                        Vec3::new(x + s + 0.25, y + 0.08, z + 2.75),
                    ),
                    1 => (
                        Vec3::new(x + s - 0.25, y, z - 2.75),
                        Vec3::new(x + s + 0.25, y + 0.08, z - 2.5),
                    ),
                    2 => (
                        Vec3::new(x + 2.5, y, z + s - 0.25),
                        Vec3::new(x + 2.75, y + 0.08, z + s + 0.25),
                    ),
                    _ => (
                        Vec3::new(x - 2.75, y, z + s - 0.25),
                        Vec3::new(x - 2.5, y + 0.08, z + s + 0.25),
                    ),
                };
                ledges.append(&primitives::cuboid(lo, hi));
                k += 1;
            }
        }
    }
    objects.push(object("ledges", ledges, Role::BOTH));
    count += k;
    // Posts (street lights, bollards) along both streets take the remaining budget.
    let rest = target.saturating_sub(ground_tris + count * 12);
    let posts = 48u32;
    let per_post = (rest / posts).max(12);
    for k in 0..posts {
        let t = (k / 4) as f32 * 4.0 - 22.0;
        let side = if k % 2 == 0 { 1.6 } else { -1.6 };
        let along_x = (k / 2) % 2 == 0;
        let (x, z) = if along_x {
            (t, 4.0 + side)
        } else {
            (4.0 + side, t)
        };
        let m = primitives::cylinder_with_triangles(0.12, 3.5, per_post)
            .transformed(Mat4::from_translation(Vec3::new(x, 0.0, z)));
        objects.push(object(&format!("post{k}"), m, Role::BOTH));
    }
    Scene::new(
        objects,
        Camera::looking_at(Vec3::new(4.0, 14.0, 34.0), Vec3::new(4.0, 0.0, 0.0), 50.0),
        Light::Sphere {
            center: Vec3::new(40.0, 80.0, 20.0),
            radius: 3.0,
        },
    )
}

/// Share of the fern's triangle budget in leaflets (the ground receiver takes the rest), and a
/// leaflet's quads along and across: open strips whose boundary edges are all silhouettes,
/// giving about 13K silhouette edges for 212K triangles as the fern of paper 004 (Table 2).
const LEAFLET_SHARE_PERCENT: u32 = 23;
const LEAFLET_QUADS: (u32, u32) = (6, 4);

fn fern(p: &GeneratorParams, target: u32) -> Scene {
    let (nu, nv) = LEAFLET_QUADS;
    let leaflet_tris = 2 * nu * nv;
    let leaflets = (target * LEAFLET_SHARE_PERCENT / 100 / leaflet_tris).max(2);
    let fronds = 10u32;
    let per_frond = leaflets.div_ceil(fronds);
    let mut plant = Mesh::default();
    let mut made = 0u32;
    for f in 0..fronds {
        let yaw = std::f32::consts::TAU * (f as f32 + 0.3 * unit_f32(mix64(p.seed ^ f as u64)))
            / fronds as f32;
        let dir = Vec3::new(yaw.cos(), 0.0, yaw.sin());
        let side = Vec3::new(-dir.z, 0.0, dir.x);
        for k in 0..per_frond {
            if made == leaflets {
                break;
            }
            made += 1;
            // Along the frond (an arch rising then falling), leaflets alternate sides and
            // shrink towards the tip.
            let t = (k / 2) as f32 / (per_frond / 2).max(1) as f32;
            let base = dir * (0.3 + 2.2 * t) + Vec3::Y * (0.4 + 1.6 * t * (1.0 - t) * 2.0);
            let s = if k % 2 == 0 { 1.0 } else { -1.0 };
            let len = 0.45 * (1.0 - 0.7 * t);
            let leaf = primitives::grid(nu, nv, |u, v| {
                let across = (v - 0.5) * 0.25 * len * (1.0 - u);
                base + side * (s * u * len) + dir * across - Vec3::Y * (0.15 * u * u * len)
            });
            plant.append(&leaf);
        }
    }
    let plant_tris = plant.triangles.len() as u32;
    let objects = vec![
        ground(4.0, target.saturating_sub(plant_tris).max(2)),
        object("fern", plant, Role::BOTH),
    ];
    Scene::new(
        objects,
        Camera::looking_at(Vec3::new(0.0, 3.5, 5.5), Vec3::new(0.0, 0.3, 0.0), 50.0),
        Light::Sphere {
            center: Vec3::new(1.5, 6.0, 1.0),
            radius: 0.4,
        },
    )
}

/// Mesh primitives. Closed primitives are 2-manifold with outward, counter-clockwise winding.
pub mod primitives {
    use super::*;

    /// An `n`×`n` grid on y = 0 spanning [-half, half]², facing +y.
    pub fn plane(half: f32, n: u32) -> Mesh {
        grid(n, n, |u, v| {
            Vec3::new((u * 2.0 - 1.0) * half, 0.0, (v * 2.0 - 1.0) * half)
        })
    }

    /// A grid of `nu`×`nv` quads mapped through `f(u, v)`, u, v in [0,1]; with `f` = identity-ish
    /// mappings the triangles face along (∂f/∂v × ∂f/∂u).
    pub fn grid(nu: u32, nv: u32, f: impl Fn(f32, f32) -> Vec3) -> Mesh {
        let mut m = Mesh::default();
        for j in 0..=nv {
            for i in 0..=nu {
                m.positions
                    .push(f(i as f32 / nu as f32, j as f32 / nv as f32));
            }
        }
        let row = nu + 1;
        for j in 0..nv {
            for i in 0..nu {
                let a = j * row + i;
                let (b, c, d) = (a + 1, a + row, a + row + 1);
                m.triangles.push([a, c, b]);
                m.triangles.push([b, c, d]);
            }
        }
        m
    }

    /// Axis-aligned box with 12 triangles.
    pub fn cuboid(min: Vec3, max: Vec3) -> Mesh {
        tessellated_cuboid(min, max, 1)
    }

    /// Axis-aligned box, each face split into `n`×`n` quads, with shared vertices along edges
    /// (welded by adjacency) so the mesh is closed.
    pub fn tessellated_cuboid(min: Vec3, max: Vec3, n: u32) -> Mesh {
        let size = max - min;
        let mut m = Mesh::default();
        // Each face: origin corner and axes (a, b), a along v and b along u; a × b points outwards.
        let faces: [(Vec3, Vec3, Vec3); 6] = [
            (Vec3::new(0.0, 0.0, 0.0), Vec3::X, Vec3::Z), // bottom (-y)
            (Vec3::new(0.0, 1.0, 0.0), Vec3::Z, Vec3::X), // top (+y)
            (Vec3::new(0.0, 0.0, 0.0), Vec3::Y, Vec3::X), // back (-z)
            (Vec3::new(0.0, 0.0, 1.0), Vec3::X, Vec3::Y), // front (+z)
            (Vec3::new(0.0, 0.0, 0.0), Vec3::Z, Vec3::Y), // left (-x)
            (Vec3::new(1.0, 0.0, 0.0), Vec3::Y, Vec3::Z), // right (+x)
        ];
        for (o, a, b) in faces {
            let f = grid(n, n, |u, v| min + (o + a * v + b * u) * size);
            m.append(&f);
        }
        m
    }

    /// UV sphere of radius 1 with `slices` around and `stacks` from pole to pole;
    /// 2·slices·(stacks−1) triangles.
    pub fn uv_sphere(slices: u32, stacks: u32) -> Mesh {
        let (slices, stacks) = (slices.max(3), stacks.max(2));
        let mut m = Mesh::default();
        m.positions.push(Vec3::Y);
        for j in 1..stacks {
            let phi = std::f32::consts::PI * j as f32 / stacks as f32;
            for i in 0..slices {
                let theta = std::f32::consts::TAU * i as f32 / slices as f32;
                m.positions.push(Vec3::new(
                    phi.sin() * theta.cos(),
                    phi.cos(),
                    -phi.sin() * theta.sin(),
                ));
            }
        }
        m.positions.push(Vec3::NEG_Y);
        let south = m.positions.len() as u32 - 1;
        let ring = |j: u32, i: u32| 1 + (j - 1) * slices + (i % slices);
        for i in 0..slices {
            m.triangles.push([0, ring(1, i), ring(1, i + 1)]);
            m.triangles
                .push([south, ring(stacks - 1, i + 1), ring(stacks - 1, i)]);
        }
        for j in 1..stacks - 1 {
            for i in 0..slices {
                let (a, b) = (ring(j, i), ring(j, i + 1));
                let (c, d) = (ring(j + 1, i), ring(j + 1, i + 1));
                m.triangles.push([a, c, d]);
                m.triangles.push([a, d, b]);
            }
        }
        m
    }

    /// A unit UV sphere with about `t` triangles (slices = 2·stacks).
    pub fn uv_sphere_with_triangles(t: u32) -> Mesh {
        let slices = ((t as f32).sqrt().round() as u32).max(4);
        let stacks = (t / (2 * slices) + 1).max(2);
        uv_sphere(slices, stacks)
    }

    /// Capped cylinder on y = 0 of `radius` and `height`, `slices` around, `rings` along;
    /// 2·slices·rings + 2·slices triangles.
    pub fn cylinder(radius: f32, height: f32, slices: u32, rings: u32) -> Mesh {
        let (slices, rings) = (slices.max(3), rings.max(1));
        let mut m = Mesh::default();
        for j in 0..=rings {
            let y = height * j as f32 / rings as f32;
            for i in 0..slices {
                let t = std::f32::consts::TAU * i as f32 / slices as f32;
                m.positions
                    .push(Vec3::new(radius * t.cos(), y, -radius * t.sin()));
            }
        }
        let at = |j: u32, i: u32| j * slices + i % slices;
        for j in 0..rings {
            for i in 0..slices {
                let (a, b, c, d) = (at(j, i), at(j, i + 1), at(j + 1, i), at(j + 1, i + 1));
                m.triangles.push([a, b, d]);
                m.triangles.push([a, d, c]);
            }
        }
        let bottom = m.positions.len() as u32;
        m.positions.push(Vec3::ZERO);
        let top = bottom + 1;
        m.positions.push(Vec3::new(0.0, height, 0.0));
        for i in 0..slices {
            m.triangles.push([bottom, at(0, i + 1), at(0, i)]);
            m.triangles.push([top, at(rings, i), at(rings, i + 1)]);
        }
        m
    }

    pub fn cylinder_with_triangles(radius: f32, height: f32, t: u32) -> Mesh {
        let slices = ((t as f32 / 4.0).round() as u32).clamp(3, 256);
        let rings = (t / (2 * slices)).saturating_sub(1).max(1);
        cylinder(radius, height, slices, rings)
    }

    /// Torus in the xz plane with major radius `r_major` and tube radius `r_minor`; 2·m·n triangles.
    pub fn torus(r_major: f32, r_minor: f32, m_major: u32, n_minor: u32) -> Mesh {
        let (mm, nn) = (m_major.max(3), n_minor.max(3));
        let mut m = Mesh::default();
        for i in 0..mm {
            let u = std::f32::consts::TAU * i as f32 / mm as f32;
            for j in 0..nn {
                let v = std::f32::consts::TAU * j as f32 / nn as f32;
                let r = r_major + r_minor * v.cos();
                m.positions
                    .push(Vec3::new(r * u.cos(), r_minor * v.sin(), -r * u.sin()));
            }
        }
        let at = |i: u32, j: u32| (i % mm) * nn + (j % nn);
        for i in 0..mm {
            for j in 0..nn {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
                m.triangles.push([a, b, d]);
                m.triangles.push([a, d, c]);
            }
        }
        m
    }

    pub fn torus_with_triangles(r_major: f32, r_minor: f32, t: u32) -> Mesh {
        let n = ((t as f32 / 2.0 / 3.0).sqrt().round() as u32).max(3);
        let m = (t / (2 * n)).max(3);
        torus(r_major, r_minor, m, n)
    }

    /// An `n`×`n` height field over [-half, half]² from fractal value noise, amplitude `amp`.
    pub fn fractal_terrain(half: f32, n: u32, amp: f32, seed: u64) -> Mesh {
        grid(n, n, |u, v| {
            let mut h = 0.0;
            let (mut f, mut a) = (2.0, 1.0);
            for octave in 0..5u64 {
                h += a * value_noise(u * f, v * f, seed.wrapping_add(octave));
                f *= 2.0;
                a *= 0.5;
            }
            Vec3::new(
                (u * 2.0 - 1.0) * half,
                amp * (h - 0.9),
                (v * 2.0 - 1.0) * half,
            )
        })
    }

    fn value_noise(x: f32, y: f32, seed: u64) -> f32 {
        let (xi, yi) = (x.floor(), y.floor());
        let (fx, fy) = (x - xi, y - yi);
        let corner = |dx: f32, dy: f32| {
            let k =
                ((xi + dx) as i64 as u64).wrapping_mul(0x9E37) ^ ((yi + dy) as i64 as u64) << 20;
            unit_f32(mix64(seed ^ mix64(k)))
        };
        let s = |t: f32| t * t * (3.0 - 2.0 * t);
        let (sx, sy) = (s(fx), s(fy));
        let top = corner(0.0, 0.0) * (1.0 - sx) + corner(1.0, 0.0) * sx;
        let bottom = corner(0.0, 1.0) * (1.0 - sx) + corner(1.0, 1.0) * sx;
        top * (1.0 - sy) + bottom * sy
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::adjacency::{EdgeAdjacency, EdgeKind};

    #[test]
    fn closed_primitives_are_closed_and_outward() {
        let meshes = [
            primitives::tessellated_cuboid(Vec3::ZERO, Vec3::ONE, 3),
            primitives::uv_sphere(12, 6),
            primitives::cylinder(1.0, 2.0, 10, 3),
            primitives::torus(1.0, 0.3, 12, 8),
        ];
        for m in meshes {
            let adj = EdgeAdjacency::build(&m);
            assert_eq!(adj.count(EdgeKind::Boundary), 0);
            assert_eq!(adj.count(EdgeKind::NonManifold), 0);
            // Outward winding: the signed volume (divergence theorem) is positive.
            let vol: f32 = (0..m.triangles.len())
                .map(|t| {
                    let [a, b, c] = m.triangle(t);
                    a.dot(b.cross(c)) / 6.0
                })
                .sum();
            assert!(vol > 0.0, "volume {vol}");
        }
    }

    #[test]
    fn the_blob_is_closed_and_rests_at_the_occluder_height() {
        let s = find("blob-on-plane").unwrap().build(&GeneratorParams {
            triangles: Some(3_000),
            occluder_height: Some(0.7),
            ..Default::default()
        });
        let blob = &s.objects[1].mesh;
        let adj = EdgeAdjacency::build(blob);
        assert_eq!(adj.count(EdgeKind::Boundary), 0);
        assert_eq!(adj.count(EdgeKind::NonManifold), 0);
        assert!((blob.bounds().min.y - 0.7).abs() < 1e-5);
    }

    #[test]
    fn the_occluder_offset_translates_the_moving_occluders_only() {
        let d = 0.75;
        for g in GENERATORS.iter().filter(|g| g.moves_laterally) {
            let p = GeneratorParams {
                triangles: Some(2_000),
                ..Default::default()
            };
            let (a, b) = (
                g.build(&p),
                g.build(&GeneratorParams {
                    occluder_offset: Some(d),
                    ..p
                }),
            );
            assert_eq!(a.light, b.light, "{}", g.name);
            assert_eq!(a.objects.len(), b.objects.len(), "{}", g.name);
            let mut moved = 0;
            for (oa, ob) in a.objects.iter().zip(&b.objects) {
                assert_eq!(oa.mesh.triangles, ob.mesh.triangles, "{}", g.name);
                if oa.mesh.positions == ob.mesh.positions {
                    continue;
                }
                // Every vertex of a moved object goes exactly d along x; receivers stay.
                assert!(oa.role.occluder, "{}: {} moved", g.name, oa.name);
                for (u, v) in oa.mesh.positions.iter().zip(&ob.mesh.positions) {
                    let delta = *v - *u;
                    assert!(
                        (delta - Vec3::X * d).abs().max_element() < 1e-5,
                        "{}: {} moved by {delta}",
                        g.name,
                        oa.name
                    );
                }
                moved += 1;
            }
            assert!(moved > 0, "{}: nothing moved", g.name);
            // The ground under the occluders stays where it was.
            assert_eq!(a.objects[0].mesh.positions, b.objects[0].mesh.positions);
        }
    }

    #[test]
    fn the_occluder_height_moves_geometry_exactly_where_a_generator_says_it_does() {
        for g in GENERATORS {
            let p = GeneratorParams {
                triangles: Some(2_000),
                ..Default::default()
            };
            let positions = |h: f32| -> Vec<Vec3> {
                g.build(&GeneratorParams {
                    occluder_height: Some(h),
                    ..p
                })
                .objects
                .iter()
                .flat_map(|o| o.mesh.positions.iter().copied())
                .collect()
            };
            assert_eq!(
                positions(0.3) != positions(0.6),
                g.moves_vertically,
                "{}",
                g.name
            );
        }
    }

    #[test]
    fn generators_hit_their_triangle_targets() {
        for g in GENERATORS {
            for target in [2_000u32, 20_000] {
                let s = g.build(&GeneratorParams {
                    triangles: Some(target),
                    ..Default::default()
                });
                let n = s.triangle_count() as f32;
                if g.name == "plate-on-plane" {
                    continue; // a plate has a fixed 12 triangles; the ground takes the rest
                }
                let rel = (n - target as f32).abs() / target as f32;
                assert!(
                    rel < 0.25,
                    "{}: {} triangles for target {}",
                    g.name,
                    n,
                    target
                );
            }
        }
    }

    #[test]
    fn generators_are_deterministic() {
        for g in GENERATORS {
            let p = GeneratorParams {
                seed: 7,
                ..Default::default()
            };
            let (a, b) = (g.build(&p).flatten(), g.build(&p).flatten());
            assert_eq!(a.mesh.positions, b.mesh.positions, "{}", g.name);
        }
    }
}
