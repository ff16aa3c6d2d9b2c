"""SceneRenderer: draws a SceneState from an OrbitCamera into an RGBA image with OpenGL.

Passes per frame, shaped by what software GL (llvmpipe) is slow at: per-pixel work and triangles.
  1. sky and ground (ray-cast, grid, haze) into a background buffer, only when the camera or
     the size changed; otherwise the cached colour and depth are copied in;
  2. the ground shadow map: occluders flattened onto the ground along the light (MAX-blended),
     blurred, then multiplied onto the ground square it covers;
  3. keyframe ghosts into a layer of their own (depth pre-pass, so each reads as one translucent
     shell), only when the camera or the ghosts changed: they stand still while a clip plays;
  4. bodies (capsules; spheres as ray-cast impostors), objects, paths, the ghost layer laid
     over them at its own depth, additive contact glows; then read back.
Images come out top row first: the projection flips y (and triangle winding with it) rather
than the CPU flipping pixels.
"""
from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from ..body import HAND_RADIUS, hand_centres
from ..geometry.rotations import quat_to_matrix
from ..objects import ObjectSpec
from .bodies import body_instances
from .camera import OrbitCamera
from .context import load_program, shared_context
from .example import warm_up_scenes
from .instances import InstanceStream, UnitMesh
from .meshes import object_triangles, ribbon_quad, unit_quad, unit_ring
from .scene import Polyline, SceneState

Y_FLIP = np.diag([1.0, -1.0, 1.0, 1.0]).astype(np.float32)
CAPSULE_FORMAT, CAPSULE_ATTRS = "3f 3f 2f 4f", ("i_a", "i_b", "i_radius", "i_color")
SPHERE_FORMAT, SPHERE_ATTRS = "3f 1f 4f", ("i_centre", "i_radius", "i_color")
PATH_FORMAT, PATH_ATTRS = "3f 3f 2f 4f 2f", ("i_p0", "i_p1", "i_arc", "i_color", "i_style")


@dataclass
class RenderConfig:
    samples: int = 0                 # MSAA samples (clamped to the driver's); llvmpipe pays ~2x for 4
    background: str = "#dfe3e8"      # horizon haze
    zenith: str = "#b9c6d3"
    ground: str = "#d9d5cc"
    haze_distance: float = 28.0      # metres over which the ground fades into the horizon
    light_direction: tuple[float, float, float] = (-0.5, 1.0, 0.3)  # towards the key light
    shadow_resolution: int = 256     # texels across the shadow map
    shadow_strength: float = 0.6     # darkest shadow multiplies the ground by 1 - this
    shadow_fade_height: float = 2.4  # occluders this high cast the faintest shadow
    shadow_blur_texels: float = 1.6  # tap spacing of the blur: wider = softer
    object_color: str = "#b48a5c"    # light wood
    ghost_alpha: float = 0.45         # one translucent layer per keyframe ghost
    contact_color: str = "#ffd166"
    target_path_width: float = 4.0   # pixels, dashed
    generated_path_width: float = 2.5  # pixels, solid
    dash_length: float = 0.12        # metres per dash and gap


def srgb_to_linear(hex_color: str, alpha: float = 1.0) -> np.ndarray:
    """'#rrggbb' -> (4,) float32 linear rgba, with the shaders' gamma of 2."""
    rgb = np.array([int(hex_color[i:i + 2], 16) for i in (1, 3, 5)], np.float32) / 255.0
    return np.append(rgb ** 2, alpha).astype(np.float32)


def _gl(m: np.ndarray) -> bytes:
    """Row-major (4, 4) -> the column-major bytes GL expects."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


class SceneRenderer:
    """Renders SceneStates at a fixed size; `resize` changes it. Not thread-safe: use it from
    the thread that first touched the shared context."""

    def __init__(self, width: int, height: int, config: RenderConfig | None = None):
        self.config = cfg = config or RenderConfig()
        self.ctx = ctx = shared_context()
        self.samples = min(cfg.samples, ctx.max_samples) if cfg.samples > 1 else 0
        self._light = np.asarray(cfg.light_direction, np.float32)
        self._light /= np.linalg.norm(self._light)

        self.prog_sky = load_program(ctx, "sky_ground", "sky_ground")
        self.prog_blur = load_program(ctx, "fullscreen", "blur")
        self.prog_ground_shadow = load_program(ctx, "ground_shadow", "ground_shadow")
        capsule, sphere, self.prog_mesh = (load_program(ctx, v, f) for v, f in
                                           (("capsule", "lit"), ("sphere", "sphere"), ("mesh", "lit")))
        capsule_shadow, sphere_shadow, self.prog_mesh_shadow = (
            load_program(ctx, v, f) for v, f in
            (("capsule", "shadow"), ("sphere", "sphere_shadow"), ("mesh", "shadow")))
        capsule_depth, sphere_depth = load_program(ctx, "capsule", "depth"), load_program(ctx, "sphere", "sphere_depth")
        self.prog_path = load_program(ctx, "path", "path")
        self.prog_glow = load_program(ctx, "glow", "glow")
        self.prog_layer = load_program(ctx, "fullscreen", "layer")
        self._programs = [self.prog_sky, self.prog_blur, self.prog_ground_shadow, capsule, sphere,
                          self.prog_mesh, capsule_shadow, sphere_shadow, self.prog_mesh_shadow,
                          capsule_depth, sphere_depth, self.prog_path, self.prog_glow, self.prog_layer]
        # Programs that see the scene through the camera (the depth-only ones draw the ghosts' pre-pass).
        self.camera_programs = [capsule, sphere, self.prog_mesh, capsule_depth, sphere_depth]
        self.shadow_programs = [capsule_shadow, sphere_shadow, self.prog_mesh_shadow]

        ring, quad, ribbon = self._meshes = [UnitMesh(ctx, unit_ring(), "in_ring"),
                                             UnitMesh(ctx, unit_quad(), "in_corner"),
                                             UnitMesh(ctx, ribbon_quad(), "in_corner")]
        self.bones = InstanceStream(ctx, ring, [capsule, capsule_shadow], CAPSULE_FORMAT, CAPSULE_ATTRS)
        self.spheres = InstanceStream(ctx, quad, [sphere, sphere_shadow], SPHERE_FORMAT, SPHERE_ATTRS)
        self.ghost_bones = InstanceStream(ctx, ring, [capsule, capsule_depth], CAPSULE_FORMAT, CAPSULE_ATTRS)
        self.ghost_spheres = InstanceStream(ctx, quad, [sphere, sphere_depth], SPHERE_FORMAT, SPHERE_ATTRS)
        self.paths = InstanceStream(ctx, ribbon, [self.prog_path], PATH_FORMAT, PATH_ATTRS)
        self.glows = InstanceStream(ctx, quad, [self.prog_glow], SPHERE_FORMAT, SPHERE_ATTRS)
        self._streams = [self.bones, self.spheres, self.ghost_bones, self.ghost_spheres, self.paths, self.glows]
        self._object_vaos: dict[tuple, tuple] = {}
        self._overlay_key: bytes | None = None  # what the ghost and path streams hold
        self._ghost_sphere_rows = np.zeros((0, 8), np.float32)
        self._vao_sky = ctx.vertex_array(self.prog_sky, [])
        self._vao_blur = ctx.vertex_array(self.prog_blur, [])
        self._vao_layer = ctx.vertex_array(self.prog_layer, [])
        self._vao_ground_shadow = ctx.vertex_array(self.prog_ground_shadow, [quad.layout], index_buffer=quad.indices,
                                                   index_element_size=4)

        n, m = cfg.shadow_resolution, cfg.shadow_resolution // 2
        # The raw map keeps contact shadows crisp; the blur runs at half its resolution, where
        # it costs a quarter (each blurred texel reads ten raw ones, and llvmpipe pays per read).
        self._shadow_tex = [ctx.texture(size, 1) for size in ((n, n), (m, m), (m, m))]  # raw, half-, blurred
        for tex in self._shadow_tex:
            tex.repeat_x = tex.repeat_y = False
        self._shadow_fbo = [ctx.framebuffer([t]) for t in self._shadow_tex]
        self.width = self.height = 0
        self._targets: list = []
        self.resize(width, height)

    # ---- size and targets ------------------------------------------------------------------
    def resize(self, width: int, height: int, display_scale: float = 1.0) -> None:
        """Render at width x height pixels. display_scale: screen pixels per rendered pixel,
        for an image that will be shown enlarged; widths given in pixels (paths) stay as wide
        on screen."""
        self.display_scale = float(display_scale)
        width, height = max(1, int(width)), max(1, int(height))
        if (width, height) == (self.width, self.height):
            return
        for t in self._targets:
            t.release()
        self.width, self.height = width, height
        self._targets = []
        self._fbo = self._framebuffer(self.samples)
        self._background = self._framebuffer(self.samples)
        self._background_key = None
        self._resolve_fbo = self._framebuffer(0, depth=False) if self.samples else self._fbo
        self._ghost_color = self.ctx.texture((width, height), 4)
        self._ghost_depth = self.ctx.depth_texture((width, height))
        self._ghost_depth.compare_func = ""  # read as plain depth values, not as a shadow sampler
        self._ghost_fbo = self.ctx.framebuffer([self._ghost_color], self._ghost_depth)
        self._targets += [self._ghost_color, self._ghost_depth, self._ghost_fbo]
        self._ghost_key, self._ghost_rect = None, (0, 0, width, height)
        self.image = np.empty((height, width, 4), np.uint8)

    def _framebuffer(self, samples: int, depth: bool = True) -> moderngl.Framebuffer:
        size = (self.width, self.height)
        color = self.ctx.renderbuffer(size, 4, samples=samples)
        depth_rb = self.ctx.depth_renderbuffer(size, samples=samples) if depth else None
        fbo = self.ctx.framebuffer([color], depth_rb)
        self._targets += [t for t in (color, depth_rb, fbo) if t is not None]
        return fbo

    # ---- drawing ---------------------------------------------------------------------------
    def warm_up(self) -> None:
        """Draw the built-in example scene (bodies, object, ghosts, paths, glows, shadow), step
        by step (example.warm_up_scenes). Software GL compiles each shader at its first draw, up
        to a second on two cores (much less once Mesa's disk cache holds them); doing it here
        keeps that off the first frame a person waits for. The image is left as it was."""
        for scene in warm_up_scenes():
            self.draw(scene)
        self.ctx.finish()

    def render(self, scene: SceneState, camera: OrbitCamera | None = None) -> np.ndarray:
        """Draw `scene` seen by `camera` (None: framed to fit). Returns the renderer's (H, W, 4)
        uint8 RGBA image, top row first; the next call overwrites it (copy it to keep it)."""
        self.draw(scene, camera)
        return self.read()

    def draw(self, scene: SceneState, camera: OrbitCamera | None = None) -> None:
        """The GL half of render: queue every pass (software GL may still be drawing after it
        returns; read waits for it)."""
        ctx = self.ctx
        if camera is None:
            camera = OrbitCamera()
            camera.frame_all(scene.points(), self.width / self.height)
        view = camera.view_matrix()
        proj = Y_FLIP @ camera.projection_matrix(self.width / self.height)
        view_proj = proj @ view
        eye = camera.eye().astype(np.float32)

        self._upload(scene)
        region = self._shadow_region(scene)
        self._draw_shadow_map(scene, region, eye)
        self._draw_background(view_proj)
        uniforms = {"u_view_proj": _gl(view_proj), "u_eye": eye.tobytes(), "u_light_dir": self._light.tobytes(),
                    "u_clip_z": view_proj[2].tobytes(), "u_clip_w": view_proj[3].tobytes()}
        for prog in self.camera_programs:
            for name, value in uniforms.items():
                if name in prog:
                    prog[name].write(value)
        self._draw_ghost_layer(view_proj, focal=abs(float(proj[1, 1])))
        ctx.copy_framebuffer(self._fbo, self._background)
        self._fbo.use()
        self._fbo.depth_mask = True
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.DST_COLOR, moderngl.ZERO
        self.prog_ground_shadow["u_view_proj"].write(_gl(view_proj))
        self.prog_ground_shadow["u_shadow_region"].value = tuple(region)
        self.prog_ground_shadow["u_shadow_strength"].value = self.config.shadow_strength
        self.prog_ground_shadow["u_soft"].value = 0
        self.prog_ground_shadow["u_sharp"].value = 1
        self._shadow_tex[2].use(0)
        self._shadow_tex[0].use(1)
        self._vao_ground_shadow.render()
        ctx.disable(moderngl.BLEND)

        ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.depth_func = "<="
        ctx.front_face = "cw"  # the y-flipped projection mirrors every triangle's winding
        self.bones.draw()
        self.spheres.draw()
        self._draw_objects(scene, shadow=False)
        ctx.disable(moderngl.CULL_FACE)
        self._draw_overlays(view, proj, view_proj)
        ctx.front_face = "ccw"
        ctx.disable(moderngl.DEPTH_TEST)

    def read(self) -> np.ndarray:
        """The last draw's pixels: the renderer's (H, W, 4) uint8 RGBA image, top row first."""
        if self.samples:
            self.ctx.copy_framebuffer(self._resolve_fbo, self._fbo)
        self._resolve_fbo.read_into(self.image, components=4)
        return self.image

    def _draw_background(self, view_proj: np.ndarray) -> None:
        """Sky and ground into the background buffer, unless the camera has not moved."""
        key = view_proj.tobytes()
        if key == self._background_key:
            return
        cfg, sky = self.config, self.prog_sky
        self._background.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.depth_func = "1"  # moderngl spells GL_ALWAYS "1"
        sky["u_inv_view_proj"].write(_gl(np.linalg.inv(view_proj)))
        sky["u_clip_z"].value = tuple(view_proj[2])
        sky["u_clip_w"].value = tuple(view_proj[3])
        sky["u_ground_color"].value = tuple(srgb_to_linear(cfg.ground)[:3])
        sky["u_horizon_color"].value = tuple(srgb_to_linear(cfg.background)[:3])
        sky["u_zenith_color"].value = tuple(srgb_to_linear(cfg.zenith)[:3])
        sky["u_haze_distance"].value = cfg.haze_distance
        self._vao_sky.render(vertices=3)
        self.ctx.disable(moderngl.DEPTH_TEST)
        self._background_key = key

    def _draw_ghost_layer(self, view_proj: np.ndarray, focal: float) -> None:
        """The keyframe ghosts alone into the ghost layer: premultiplied colour over transparent
        and the depth of each pixel's nearest ghost, unless the camera and the ghosts are as
        they were. Also notes the screen rectangle they cover, which bounds the per-frame cost
        of laying the layer over the scene."""
        key = (view_proj.tobytes(), self._overlay_key)
        if key == self._ghost_key or not self.ghost_bones.count:
            return
        self._ghost_key, ctx, fbo = key, self.ctx, self._ghost_fbo
        self._ghost_rect = _screen_rect(self._ghost_sphere_rows, view_proj, focal, self.width, self.height)
        fbo.use()
        fbo.depth_mask = True
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        ctx.depth_func = "<="
        ctx.front_face = "cw"  # the y-flipped projection mirrors every triangle's winding
        # Depth first, then colour where depth matches: one translucent layer per ghost.
        # The depth pass blends its colour away: moderngl 5.13's color_mask does not reach GL.
        ctx.blend_func = moderngl.ZERO, moderngl.ONE
        self.ghost_bones.draw(1)
        self.ghost_spheres.draw(1)
        fbo.depth_mask = False
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA, moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        self.ghost_bones.draw()
        self.ghost_spheres.draw()
        fbo.depth_mask = True
        ctx.front_face = "ccw"
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)

    def _draw_overlays(self, view: np.ndarray, proj: np.ndarray, view_proj: np.ndarray) -> None:
        """Paths, the ghost layer and glows, over the opaque scene, without writing depth."""
        ctx, cfg = self.ctx, self.config
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        self.prog_path["u_view_proj"].write(_gl(view_proj))
        self.prog_path["u_viewport"].value = (self.width * self.display_scale, self.height * self.display_scale)
        self.prog_path["u_dash_length"].value = cfg.dash_length
        self._fbo.depth_mask = False
        self.paths.draw()
        if self.ghost_bones.count:
            ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
            self.prog_layer["u_color"].value = 0
            self.prog_layer["u_depth"].value = 1
            self._ghost_color.use(0)
            self._ghost_depth.use(1)
            self._fbo.scissor = self._ghost_rect
            self._vao_layer.render(vertices=3)
            self._fbo.scissor = None
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        self.prog_glow["u_view"].write(_gl(view))
        self.prog_glow["u_proj"].write(_gl(proj))
        self.glows.draw()
        self._fbo.depth_mask = True
        ctx.disable(moderngl.BLEND)

    def _upload(self, scene: SceneState) -> None:
        cfg = self.config
        people = np.asarray(scene.people, np.float32).reshape(-1, 22, 3)
        bones, spheres = self._bodies([people], 1.0, scene)
        self.bones.upload(bones)
        self.spheres.upload(spheres)
        # Ghosts and paths stay the same from frame to frame while a clip plays; building their
        # rows costs about a millisecond, comparing what they are made of a few microseconds.
        key = _overlay_key(scene)
        if key != self._overlay_key:
            self._overlay_key = key
            bones, self._ghost_sphere_rows = self._bodies(scene.ghosts, cfg.ghost_alpha, scene)
            self.ghost_bones.upload(bones)
            self.ghost_spheres.upload(self._ghost_sphere_rows)
            rows = [_path_rows(p, cfg.target_path_width, dashed=True, alpha=0.85) for p in scene.target_paths]
            rows += [_path_rows(p, cfg.generated_path_width, dashed=False, alpha=0.95) for p in scene.generated_paths]
            self.paths.upload(np.concatenate(rows) if rows else np.zeros((0, 14), np.float32))
        glows = np.zeros((0, 8), np.float32)
        if scene.contact is not None and len(people):
            on = np.asarray(scene.contact)[: len(people)] > 0.5   # (H, 2)
            glows = np.zeros((int(on.sum()), 8), np.float32)
            glows[:, 0:3] = hand_centres(people)[on]
            glows[:, 3] = HAND_RADIUS * 1.6
            glows[:, 4:8] = srgb_to_linear(cfg.contact_color)
        self.glows.upload(glows)

    @staticmethod
    def _bodies(groups, alpha: float, scene: SceneState) -> tuple[np.ndarray, np.ndarray]:
        """Instance rows of every person in each group (each group (H, 22, 3))."""
        bones, spheres = [np.zeros((0, 12), np.float32)], [np.zeros((0, 8), np.float32)]
        for people in groups:
            for h, joints in enumerate(np.asarray(people, np.float32).reshape(-1, 22, 3)):
                b, s = body_instances(joints, srgb_to_linear(scene.color(h), alpha))
                bones.append(b)
                spheres.append(s)
        return np.concatenate(bones), np.concatenate(spheres)

    def _object_vao(self, spec: ObjectSpec) -> tuple:
        key = (spec.type, spec.size)
        if key not in self._object_vaos:
            buf = self.ctx.buffer(object_triangles(spec).tobytes())
            vaos = tuple(self.ctx.vertex_array(p, [(buf, "3f 3f", "in_position", "in_normal")], skip_errors=True)
                         for p in (self.prog_mesh, self.prog_mesh_shadow))
            self._object_vaos[key] = (buf, *vaos)
        return self._object_vaos[key]

    def _draw_objects(self, scene: SceneState, shadow: bool) -> None:
        prog = self.prog_mesh_shadow if shadow else self.prog_mesh
        if not shadow:
            prog["u_color"].value = tuple(srgb_to_linear(self.config.object_color))
        for obj in scene.objects:
            model = np.eye(4, dtype=np.float32)
            model[:3, :3] = quat_to_matrix(np.asarray(obj.pose[3:], np.float64))
            model[:3, 3] = obj.pose[:3]
            prog["u_model"].write(_gl(model))
            self._object_vao(obj.spec)[2 if shadow else 1].render()

    # ---- soft ground shadow ----------------------------------------------------------------
    def _shadow_region(self, scene: SceneState) -> np.ndarray:
        """(3,) centre x, centre z, half extent of the ground square the shadow map covers:
        the occluders' feet and their points slid along the light onto the ground, plus room
        for the blur. A tight square keeps the ground-shadow pass small on screen."""
        pts = [np.asarray(scene.people, float).reshape(-1, 3)]
        for o in scene.objects:
            top = np.asarray(o.pose[:3], float) + [0.0, max(o.spec.size), 0.0]
            pts.append(np.stack([o.pose[:3], top]))
        pts = np.concatenate(pts)
        if len(pts) == 0:
            return np.array([0.0, 0.0, 1.0], np.float32)
        landed = pts - pts[:, 1:2] / self._light[1] * self._light
        xz = np.concatenate([pts, landed])[:, [0, 2]]
        lo, hi = xz.min(0), xz.max(0)
        half = max(hi - lo) / 2 + 0.5
        return np.array([*(lo + hi) / 2, half], np.float32)

    def _draw_shadow_map(self, scene: SceneState, region: np.ndarray, eye: np.ndarray) -> None:
        ctx, n = self.ctx, self.config.shadow_resolution
        cx, cz, half = (float(v) for v in region)
        lx, ly, lz = self._light
        # Slide each point along the light onto y = 0, then map the region's x, z to clip x, y.
        flatten = np.array([[1, -lx / ly, 0, 0], [0, 0, 0, 0], [0, -lz / ly, 1, 0], [0, 0, 0, 1]], np.float32)
        to_clip = np.array([[1 / half, 0, 0, -cx / half], [0, 0, 1 / half, -cz / half],
                            [0, 0, 0, 0], [0, 0, 0, 1]], np.float32)
        matrix = _gl(to_clip @ flatten)
        self._shadow_fbo[0].use()  # use() also sets the framebuffer's own full-size viewport
        self._shadow_fbo[0].clear(0.0, 0.0, 0.0, 0.0)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.enable(moderngl.BLEND)
        ctx.blend_equation = moderngl.MAX
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        for prog in self.shadow_programs:
            prog["u_view_proj"].write(matrix)
            prog["u_fade_height"].value = self.config.shadow_fade_height
        # Sphere impostors face the light in this pass: a point far along it stands in for the eye.
        self.shadow_programs[1]["u_eye"].value = tuple(np.array([cx, 0.0, cz]) + 1e4 * self._light)
        self.bones.draw(1)
        self.spheres.draw(1)
        self._draw_objects(scene, shadow=True)
        ctx.blend_equation = moderngl.FUNC_ADD
        ctx.disable(moderngl.BLEND)
        step = self.config.shadow_blur_texels / n
        self.prog_blur["u_source"].value = 0
        for src, dst, direction in ((0, 1, (step, 0.0)), (1, 2, (0.0, step))):
            self._shadow_fbo[dst].use()
            self._shadow_tex[src].use(0)
            self.prog_blur["u_step"].value = direction
            self._vao_blur.render(vertices=3)

    def release(self) -> None:
        """Free this renderer's GL objects (the shared context stays)."""
        for s in self._streams:
            s.release()
        for buf, *vaos in self._object_vaos.values():
            for v in vaos:
                v.release()
            buf.release()
        for obj in [*self._shadow_fbo, *self._shadow_tex, *self._targets, self._vao_sky, self._vao_blur,
                    self._vao_layer, self._vao_ground_shadow, *self._meshes, *self._programs]:
            obj.release()
        self._object_vaos, self._targets = {}, []


def _overlay_key(scene: SceneState) -> bytes:
    """Everything the ghost and path rows are built from, as bytes to compare."""
    parts = [repr((scene.colors, len(scene.ghosts), len(scene.target_paths))).encode()]
    parts += [np.asarray(g, np.float32).tobytes() for g in scene.ghosts]
    parts += [p.color.encode() + np.asarray(p.points, np.float32).tobytes()
              for p in scene.target_paths + scene.generated_paths]
    return b"|".join(parts)


def _screen_rect(spheres: np.ndarray, view_proj: np.ndarray, focal: float, width: int,
                 height: int) -> tuple[int, int, int, int]:
    """Framebuffer pixels (x, y, w, h) that hold every sphere of `spheres`, rows (S, 8) of
    centre xyz and radius (`focal`: the projection's y scale); the whole frame when one reaches
    behind the camera. Each bone lies within the spheres at its ends, so this bounds bodies."""
    centres, radii = spheres[:, :3].astype(np.float64), spheres[:, 3].astype(np.float64)
    clip = np.c_[centres, np.ones(len(centres))] @ view_proj.T.astype(np.float64)   # (S, 4)
    w = clip[:, 3]
    if len(w) == 0 or (w - radii < 1e-3).any():
        return 0, 0, width, height
    centre = (clip[:, :2] / w[:, None] * 0.5 + 0.5) * (width, height)
    # Seen off-axis a sphere's outline stretches a little; 1.4x its radius and 2 px cover it.
    reach = 1.4 * radii * focal * height / 2 / w + 2   # (S,) pixels
    lo = np.floor(np.maximum((centre - reach[:, None]).min(0), 0)).astype(int)
    hi = np.ceil(np.minimum((centre + reach[:, None]).max(0), (width, height))).astype(int)
    return int(lo[0]), int(lo[1]), int(max(hi[0] - lo[0], 0)), int(max(hi[1] - lo[1], 0))


def _path_rows(path: Polyline, width: float, dashed: bool, alpha: float) -> np.ndarray:
    """(P, 3) polyline -> (P - 1, 14) ribbon segment rows for path.vert."""
    pts = np.asarray(path.points, np.float32).reshape(-1, 3)
    if len(pts) < 2:
        return np.zeros((0, 14), np.float32)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    rows = np.empty((len(pts) - 1, 14), np.float32)
    rows[:, 0:3], rows[:, 3:6] = pts[:-1], pts[1:]
    rows[:, 6], rows[:, 7] = arc[:-1], arc[1:]
    rows[:, 8:12] = srgb_to_linear(path.color, alpha)
    rows[:, 12], rows[:, 13] = width, float(dashed)
    return rows
