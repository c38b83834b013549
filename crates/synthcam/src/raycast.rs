//! The scene transformed into the camera frame once per frame, and the ray-object tests.
//!
//! Every ray starts at the camera centre (the origin of the camera frame) with direction
//! `d = K^-1 [u, v, 1]^T`; `d` is *not* normalised, so a hit at parameter `t` is the point
//! `t d` and parameters of different objects compare directly. Each object keeps a
//! conservative screen-space bounding box so most rays skip it with two comparisons.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::camera::PosedCamera;
use crate::error::SynthError;
use crate::scene::{Body, Face, Ground, Panel, Robot, Scene};
use crate::texture::Texture;

/// Rays must travel at least this parameter (camera-frame z, since `d.z = 1` for pixel rays)
/// before they can hit anything.
pub(crate) const T_MIN: f64 = 1e-9;

/// Diffuse lighting: a directional light plus ambient.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Light {
    /// Unit direction towards the light, world frame.
    pub dir: Vector3<f64>,
    /// Ambient fraction in `[0, 1]`.
    pub ambient: f64,
    /// Whether rig faces are shaded too.
    pub shade_faces: bool,
}

impl Light {
    fn factor(&self, normal_world: &Vector3<f64>) -> f32 {
        (self.ambient + (1.0 - self.ambient) * normal_world.dot(&self.dir).max(0.0)) as f32
    }
}

/// A screen-space bounding box (pixel coordinates), inclusive.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ScreenBox {
    pub u0: f64,
    pub u1: f64,
    pub v0: f64,
    pub v1: f64,
}

impl ScreenBox {
    #[inline]
    pub fn contains(&self, u: f64, v: f64) -> bool {
        u >= self.u0 && u <= self.u1 && v >= self.v0 && v <= self.v1
    }
}

/// A textured rectangle (or parallelogram) in the camera frame.
#[derive(Debug)]
pub(crate) struct Rect<'a> {
    normal: Vector3<f64>,
    /// `normal . corner` (plane offset).
    offset: f64,
    /// `right / width` and its offset, giving `s = t (s_dir . d) - s0`.
    s_dir: Vector3<f64>,
    s0: f64,
    /// `down / height` and its offset, giving `t = t (t_dir . d) - t0`.
    t_dir: Vector3<f64>,
    t0: f64,
    /// PosedCamera on the outward side?
    front: bool,
    texture: &'a dyn Texture,
    front_shade: f32,
    back_albedo: f32,
}

/// A box body: camera-to-box rotation and the camera centre in box coordinates.
#[derive(Debug)]
pub(crate) struct BoxBody {
    rot: Matrix3<f64>,
    origin: Vector3<f64>,
    half: Vector3<f64>,
    /// Shaded albedo of the faces -x, +x, -y, +y, -z, +z.
    shade: [f32; 6],
}

/// A cylinder body about the local z axis, `z` in `[0, height]`.
#[derive(Debug)]
pub(crate) struct CylBody {
    rot: Matrix3<f64>,
    origin: Vector3<f64>,
    radius: f64,
    height: f64,
    albedo: f32,
    ambient: f32,
    /// Light direction in the body frame (unit), or `None` without shading.
    light_body: Option<Vector3<f64>>,
    cap_shade: [f32; 2],
}

#[derive(Debug)]
pub(crate) enum Shape<'a> {
    Rect(Rect<'a>),
    Box(BoxBody),
    Cyl(CylBody),
}

/// One object of the prepared scene.
#[derive(Debug)]
pub(crate) struct Prim<'a> {
    pub shape: Shape<'a>,
    pub bbox: ScreenBox,
    /// `(robot index, face index)`; `None` face for bodies.
    pub owner: (usize, Option<usize>),
}

/// The ground plane in the camera frame.
#[derive(Debug)]
pub(crate) struct PreparedGround<'a> {
    normal: Vector3<f64>,
    offset: f64,
    /// PosedCamera centre in world, and camera->world rotation rows 0 and 1 scaled by `1 / tile`.
    eye_s: f64,
    eye_t: f64,
    row_s: Vector3<f64>,
    row_t: Vector3<f64>,
    texture: &'a dyn Texture,
    shade: f32,
}

/// The scene, ready for ray casting from one camera.
#[derive(Debug)]
pub(crate) struct Prepared<'a> {
    pub prims: Vec<Prim<'a>>,
    pub ground: Option<PreparedGround<'a>>,
    pub background: f32,
}

/// A hit: ray parameter and radiance (albedo times shading).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hit {
    pub t: f64,
    pub value: f32,
}

/// Conservative screen box of camera-frame points: `None` if all are behind the camera,
/// the whole plane if some are.
fn screen_box(camera: &PosedCamera, pts: &[Point3<f64>]) -> Option<ScreenBox> {
    let eps = pose::MIN_DEPTH;
    if pts.iter().all(|p| p.z <= eps) {
        return None;
    }
    if pts.iter().any(|p| p.z <= eps) {
        return Some(ScreenBox {
            u0: f64::NEG_INFINITY,
            u1: f64::INFINITY,
            v0: f64::NEG_INFINITY,
            v1: f64::INFINITY,
        });
    }
    let mut b = ScreenBox {
        u0: f64::INFINITY,
        u1: f64::NEG_INFINITY,
        v0: f64::INFINITY,
        v1: f64::NEG_INFINITY,
    };
    for p in pts {
        if let Some(q) = camera.project(p) {
            b.u0 = b.u0.min(q.x);
            b.u1 = b.u1.max(q.x);
            b.v0 = b.v0.min(q.y);
            b.v1 = b.v1.max(q.y);
        }
    }
    // A small margin covers rounding in the projection.
    let m = 1e-3;
    Some(ScreenBox {
        u0: b.u0 - m,
        u1: b.u1 + m,
        v0: b.v0 - m,
        v1: b.v1 + m,
    })
}

/// Brightness factor of a surface with world normal `n` under `light` (1 without light).
fn world_factor(light: Option<&Light>, n: &Vector3<f64>) -> f32 {
    light.map_or(1.0, |l| l.factor(n))
}

/// A robot's transforms as its primitives need them.
struct RobotFrame {
    b2w: Isometry3<f64>,
    b2c: Isometry3<f64>,
    /// Body-to-camera rotation and its inverse.
    rot_bc: Matrix3<f64>,
    rot_cb: Matrix3<f64>,
    /// The camera centre in the body frame.
    origin_body: Vector3<f64>,
}

impl RobotFrame {
    fn new(w2c: &Isometry3<f64>, robot: &Robot) -> Self {
        let b2w = crate::scene::body_to_world(&robot.pose);
        let b2c = w2c * b2w;
        let rot_bc = *b2c.rotation.to_rotation_matrix().matrix();
        Self {
            b2w,
            b2c,
            rot_bc,
            rot_cb: rot_bc.transpose(),
            origin_body: b2c.inverse_transform_point(&Point3::origin()).coords,
        }
    }

    /// A body-frame direction in the world frame.
    fn world_dir(&self, n: Vector3<f64>) -> Vector3<f64> {
        self.b2w.rotation * n
    }
}

/// The primitive of a robot's body (none for [`Body::None`] or a body off screen).
fn body_prim<'a>(
    camera: &PosedCamera,
    light: Option<&Light>,
    f: &RobotFrame,
    body: &Body,
    robot: usize,
) -> Option<Prim<'a>> {
    match *body {
        Body::None => None,
        Body::Box {
            length,
            width,
            height,
            albedo,
        } => {
            let half = Vector3::new(length / 2.0, width / 2.0, height / 2.0);
            let centre = Vector3::new(0.0, 0.0, height / 2.0);
            let mut shade = [0f32; 6];
            for (i, s) in shade.iter_mut().enumerate() {
                let mut n = Vector3::zeros();
                n[i / 2] = if i % 2 == 0 { -1.0 } else { 1.0 };
                *s = albedo as f32 * world_factor(light, &f.world_dir(n));
            }
            let corners: Vec<Point3<f64>> = (0..8)
                .map(|i| {
                    let c = Vector3::new(
                        if i & 1 == 0 { -half.x } else { half.x },
                        if i & 2 == 0 { -half.y } else { half.y },
                        if i & 4 == 0 { -half.z } else { half.z },
                    );
                    f.b2c * Point3::from(centre + c)
                })
                .collect();
            let bbox = screen_box(camera, &corners)?;
            Some(Prim {
                shape: Shape::Box(BoxBody {
                    rot: f.rot_cb,
                    origin: f.origin_body - centre,
                    half,
                    shade,
                }),
                bbox,
                owner: (robot, None),
            })
        }
        Body::Cylinder {
            radius,
            height,
            albedo,
        } => {
            let corners: Vec<Point3<f64>> = (0..8)
                .map(|i| {
                    let x = if i & 1 == 0 { -radius } else { radius };
                    let y = if i & 2 == 0 { -radius } else { radius };
                    let z = if i & 4 == 0 { 0.0 } else { height };
                    f.b2c * Point3::new(x, y, z)
                })
                .collect();
            let light_body = light.map(|l| f.b2w.rotation.inverse() * l.dir);
            let cap_shade = [
                albedo as f32 * world_factor(light, &f.world_dir(-Vector3::z())),
                albedo as f32 * world_factor(light, &f.world_dir(Vector3::z())),
            ];
            let bbox = screen_box(camera, &corners)?;
            Some(Prim {
                shape: Shape::Cyl(CylBody {
                    rot: f.rot_cb,
                    origin: f.origin_body,
                    radius,
                    height,
                    albedo: albedo as f32,
                    ambient: light.map_or(1.0, |l| l.ambient as f32),
                    light_body,
                    cap_shade,
                }),
                bbox,
                owner: (robot, None),
            })
        }
    }
}

/// The primitive of rig face `face` of robot `robot` (none if it is off screen).
fn face_prim<'a>(
    camera: &PosedCamera,
    light: Option<&Light>,
    f: &RobotFrame,
    face: &'a Face,
    owner: (usize, usize),
) -> Result<Option<Prim<'a>>, SynthError> {
    let frame = face.placement.frame()?;
    let corners_body = face.placement.corners()?;
    let corners: Vec<Point3<f64>> = corners_body.iter().map(|p| f.b2c * p).collect();
    let Some(bbox) = screen_box(camera, &corners) else {
        return Ok(None);
    };
    let normal = f.rot_bc * frame.normal;
    let right = f.rot_bc * frame.right;
    let down = -(f.rot_bc * frame.up);
    let nw = corners[0].coords;
    let offset = normal.dot(&nw);
    let s_dir = right / face.placement.width;
    let t_dir = down / face.placement.height;
    let front_shade = match light {
        Some(l) if l.shade_faces => l.factor(&f.world_dir(frame.normal)),
        _ => 1.0,
    };
    Ok(Some(Prim {
        shape: Shape::Rect(Rect {
            normal,
            offset,
            s_dir,
            s0: s_dir.dot(&nw),
            t_dir,
            t0: t_dir.dot(&nw),
            front: offset < 0.0,
            texture: face.texture.as_ref(),
            front_shade,
            back_albedo: face.back_albedo as f32 * world_factor(light, &f.world_dir(-frame.normal)),
        }),
        bbox,
        owner: (owner.0, Some(owner.1)),
    }))
}

/// The primitive of a free-standing panel (none if it is off screen).
fn panel_prim<'a>(
    camera: &PosedCamera,
    w2c: &Isometry3<f64>,
    panel: &'a Panel,
) -> Option<Prim<'a>> {
    let [nw, ne, sw] = panel.corners.map(|p| w2c * p);
    let se = ne + (sw - nw);
    let bbox = screen_box(camera, &[nw, ne, se, sw])?;
    let (a, b) = (ne - nw, sw - nw);
    // Outward normal, and the dual basis giving s and t from a point's offset to NW.
    let normal = b.cross(&a);
    let s_dir = b.cross(&normal) / a.dot(&b.cross(&normal));
    let t_dir = normal.cross(&a) / b.dot(&normal.cross(&a));
    let offset = normal.dot(&nw.coords);
    Some(Prim {
        shape: Shape::Rect(Rect {
            normal,
            offset,
            s_dir,
            s0: s_dir.dot(&nw.coords),
            t_dir,
            t0: t_dir.dot(&nw.coords),
            front: offset < 0.0,
            texture: panel.texture.as_ref(),
            front_shade: 1.0,
            back_albedo: panel.back_albedo as f32,
        }),
        bbox,
        owner: (usize::MAX, None),
    })
}

/// The ground plane in the camera frame, with its texture mapping.
fn prepared_ground<'a>(
    w2c: &Isometry3<f64>,
    g: &'a Ground,
    light: Option<&Light>,
) -> PreparedGround<'a> {
    let c2w = w2c.inverse();
    let normal = w2c.rotation * Vector3::z();
    let origin = w2c.translation.vector;
    let rot_wc = *c2w.rotation.to_rotation_matrix().matrix();
    let inv = 1.0 / g.tile;
    PreparedGround {
        normal,
        offset: normal.dot(&origin),
        eye_s: c2w.translation.vector.x * inv,
        eye_t: -c2w.translation.vector.y * inv,
        row_s: rot_wc.row(0).transpose() * inv,
        row_t: -rot_wc.row(1).transpose() * inv,
        texture: g.texture.as_ref(),
        shade: world_factor(light, &Vector3::z()),
    }
}

impl<'a> Prepared<'a> {
    /// Transform the (validated) scene into the camera frame.
    pub fn new(
        scene: &'a Scene,
        camera: &PosedCamera,
        light: Option<&Light>,
    ) -> Result<Self, SynthError> {
        let w2c = camera.world_to_camera();
        let mut prims = Vec::new();
        for (ri, robot) in scene.robots.iter().enumerate() {
            let frame = RobotFrame::new(w2c, robot);
            prims.extend(body_prim(camera, light, &frame, &robot.body, ri));
            for (fi, face) in robot.faces.iter().enumerate() {
                prims.extend(face_prim(camera, light, &frame, face, (ri, fi))?);
            }
        }
        prims.extend(
            scene
                .panels
                .iter()
                .filter_map(|panel| panel_prim(camera, w2c, panel)),
        );
        Ok(Self {
            prims,
            ground: scene
                .ground
                .as_ref()
                .map(|g| prepared_ground(w2c, g, light)),
            background: scene.background as f32,
        })
    }

    /// Nearest hit along `d` among objects (and the ground) with `T_MIN < t < t_max`,
    /// skipping the object `skip`. `(u, v)` is the ray's pixel position for the screen-box
    /// test, or `None` to test every object.
    #[inline]
    pub fn nearest(
        &self,
        d: &Vector3<f64>,
        uv: Option<(f64, f64)>,
        candidates: &[u32],
        t_max: f64,
        skip: Option<usize>,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        if let Some(g) = &self.ground {
            let den = g.normal.dot(d);
            let t = g.offset / den;
            if t > T_MIN && t < t_best {
                let s = t * g.row_s.dot(d) + g.eye_s;
                let tt = t * g.row_t.dot(d) + g.eye_t;
                let value = g.texture.albedo(s - s.floor(), tt - tt.floor()) * g.shade;
                t_best = t;
                best = Some(Hit { t, value });
            }
        }
        for &i in candidates {
            let i = i as usize;
            if Some(i) == skip {
                continue;
            }
            let Some(prim) = self.prims.get(i) else {
                continue;
            };
            if let Some((u, v)) = uv
                && !prim.bbox.contains(u, v)
            {
                continue;
            }
            if let Some(h) = prim.shape.hit(d, t_best) {
                t_best = h.t;
                best = Some(h);
            }
        }
        best
    }
}

impl Shape<'_> {
    #[inline]
    fn hit(&self, d: &Vector3<f64>, t_best: f64) -> Option<Hit> {
        match self {
            Shape::Rect(r) => {
                let t = r.offset / r.normal.dot(d);
                if !(t > T_MIN && t < t_best) {
                    return None;
                }
                let s = t * r.s_dir.dot(d) - r.s0;
                let tt = t * r.t_dir.dot(d) - r.t0;
                if !((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&tt)) {
                    return None;
                }
                let value = if r.front {
                    r.texture.albedo(s, tt) * r.front_shade
                } else {
                    r.back_albedo
                };
                Some(Hit { t, value })
            }
            Shape::Box(b) => {
                let dl = b.rot * d;
                let mut t_near = f64::NEG_INFINITY;
                let mut t_far = f64::INFINITY;
                let mut axis = 0usize;
                for i in 0..3 {
                    let inv = 1.0 / dl[i];
                    let t1 = (-b.half[i] - b.origin[i]) * inv;
                    let t2 = (b.half[i] - b.origin[i]) * inv;
                    let (lo, hi) = if t1 < t2 { (t1, t2) } else { (t2, t1) };
                    if lo > t_near {
                        t_near = lo;
                        // Entering through the -axis face when moving in +axis direction.
                        axis = 2 * i + usize::from(dl[i] < 0.0);
                    }
                    if hi < t_far {
                        t_far = hi;
                    }
                }
                if !(t_near <= t_far && t_near > T_MIN && t_near < t_best) {
                    return None;
                }
                Some(Hit {
                    t: t_near,
                    value: b.shade[axis],
                })
            }
            Shape::Cyl(c) => {
                let dl = c.rot * d;
                let o = &c.origin;
                let mut best: Option<Hit> = None;
                let mut t_best = t_best;
                let a = dl.x * dl.x + dl.y * dl.y;
                if a > 0.0 {
                    let b = o.x * dl.x + o.y * dl.y;
                    let cc = o.x * o.x + o.y * o.y - c.radius * c.radius;
                    let disc = b * b - a * cc;
                    if disc >= 0.0 {
                        let t = (-b - disc.sqrt()) / a;
                        let z = o.z + t * dl.z;
                        if t > T_MIN && t < t_best && (0.0..=c.height).contains(&z) {
                            let value = match &c.light_body {
                                Some(l) => {
                                    let (x, y) = (o.x + t * dl.x, o.y + t * dl.y);
                                    let lambert = ((x * l.x + y * l.y) / c.radius).max(0.0) as f32;
                                    c.albedo * (c.ambient + (1.0 - c.ambient) * lambert)
                                }
                                None => c.albedo,
                            };
                            t_best = t;
                            best = Some(Hit { t, value });
                        }
                    }
                }
                if dl.z != 0.0 {
                    for (k, zc) in [0.0, c.height].into_iter().enumerate() {
                        let t = (zc - o.z) / dl.z;
                        if t > T_MIN && t < t_best {
                            let (x, y) = (o.x + t * dl.x, o.y + t * dl.y);
                            if x * x + y * y <= c.radius * c.radius {
                                t_best = t;
                                best = Some(Hit {
                                    t,
                                    value: c.cap_shade[k],
                                });
                            }
                        }
                    }
                }
                best
            }
        }
    }
}
