"""Every limit of the engine, once. Everything else (settings, the API's schema, the
shaders' stack sizes, the scene's validation, the docs' tables) takes its bound from here.

Why each bound is what it is:

- ``MAX_TREE_DEPTH`` is the traversal stack of every tree method's shader: one stack
  entry per tree level. A build never makes a deeper tree, so no traversal can overflow;
  raising it costs every fragment that many more registers (``docs/SHADING.md``).
- ``MAX_RECURSION_DEPTH`` bounds the Whitted ray tree (the shader's task stack holds one
  entry per level plus one), and the ray engines spend one stencil bit per generation:
  8 bits of stencil cover exactly these 8 levels.
- ``MAX_PATH_DEPTH``: the path integrator keeps no ray tree (one path, one shadow ray at a time),
  so its bound is a cost bound only: 16 segments carry all but a negligible part of the
  light of the scenes here (a clear glass sphere needs ~8 for 99.9 %).
- ``MAX_IMAGE_SIDE`` is a render target's side *after* supersampling (so a frame of
  ``width × √samples_per_pixel`` must fit too); GL guarantees 4,096 on this machine
  and on most phones.
- The hierarchical ray engine draws one point sprite per tile: its side is at most
  ``MAX_TILE_SIZE`` pixels (llvmpipe allows 255; the device's own bound is checked at
  run time).
"""

from __future__ import annotations

# ---- trees ---------------------------------------------------------------------------------
MAX_TREE_DEPTH = 64  # levels (the root counts as 1) = entries of the traversal stack
MAX_PRIMS = 1 << 24  # largest leaf-size limit a build accepts
MAX_RETRIES = 64  # BIH: retries (box halvings / shrinks) of one node before it is a leaf

# ---- frames --------------------------------------------------------------------------------
MAX_IMAGE_SIDE = 4096  # pixels, of the render target (after supersampling)
MAX_RECURSION_DEPTH = 8  # levels of the ray tree; 1 = primary rays only
MAX_PATH_DEPTH = 16  # the path integrator: segments of a path (docs/SHADING.md, "Path integrator")
SAMPLES_PER_PIXEL = (1, 4, 9, 16)  # stratified supersampling: √s × √s sub-pixels
MAX_PATH_SAMPLES = 4096  # the path integrator: samples per pixel, any count 1 … this
PATH_SAMPLE_CHOICES = (1, 4, 16, 64, 256, 1024)  # the counts the client's settings sheet offers the path integrator
PATH_SAMPLES_PER_PASS = 16  # the path integrator: samples per pixel one draw traces (a frame's passes)
DEVICE_PATH_SAMPLES_PER_PASS = 4  # … one draw of a browser (device mode) traces: a phone's bands stay short
# A session's accumulation (docs/API.md, "Accumulation") grows to this many samples per pixel; past
# it, frames answer the held mean with their own samples added but keep nothing more (the sample
# index stays far inside the sampler's exact integers).
MAX_ACCUMULATED_SAMPLES = 1 << 20
# Refinement while still (docs/API.md, "Refinement"): the samples per pixel and the wall-clock time
# a session's refinement stream goes on to (0: no time of its own: until its samples, the next change,
# or the service's bound of the GL time one resting view may take, POCKETRAY_MAX_REFINE_MS).
REFINE_SAMPLES_RANGE = (1, 1 << 16)
REFINE_MS_RANGE = (0, 600_000)
REFINE_NOISE_RANGE = (0.0, 1.0)  # relative RMS error of the mean; 0: no noise target
MAX_SAMPLED_SPHERES = 8  # the path integrator: emitting spheres sampled by next-event estimation
MAX_SAMPLED_TRIANGLES = 16  # … emitting triangles (a scene with more samples none of them)
# … the surfaces of emitting analytic shapes (a cylinder's or cone's side and each cap, a disk, a
# torus: a closed cylinder is three); a scene with more samples none of them
MAX_SAMPLED_SHAPE_PATCHES = 12
EXPOSURE_RANGE = (-20.0, 20.0)  # stops: the path integrator's png/jpeg are tone-mapped from 2^exposure × radiance
MIN_WEIGHT_RANGE = (0.0, 1.0)  # ε cut-off of secondary rays
MIN_TILE_SIZE = 2  # hre: tile side in pixels
MAX_TILE_SIZE = 64
DEFAULT_TILE_SIZE = 16
JPEG_QUALITY_RANGE = (1, 100)
# A shader loop with one primitive per iteration (brute force): llvmpipe's loop limiter ends a
# loop after 65,535 iterations without an error, so past this many the last primitives are never
# tested (measured: a triangle of id 65,532 is hit, one of id 65,533 is not). Such a scene is
# refused for that method instead of drawn without them.
MAX_LOOP_PRIMITIVES = 65_533

# ---- animation -----------------------------------------------------------------------------
MAX_TIME = 1.0e6  # seconds: the largest time a scene can be posed at
UPDATE_THRESHOLD_RANGE = (0.0, 100.0)  # selective rebuild: cost growth, 0.3 = +30 %
MAX_ANGULAR_VELOCITY = 1e3  # radians per second (rigid motion)
MAX_PERIOD = 1e6  # seconds (rigid motion's oscillation)
MAX_WAVELENGTH = 1e9  # world units (deformable motion)
MAX_SPEED = 1e6  # world units per second (deformable, incoherent motion)
MAX_LIFETIME = 1e6  # seconds (incoherent motion)
MAX_ABSENT = 0.95  # fraction of a lifetime a sphere is gone (incoherent motion)
MAX_MOTION_SEED = 2**63 - 1

# ---- scenes --------------------------------------------------------------------------------
# 24 bits of mantissa: beyond 1e7 a unit sphere cannot be represented at all.
MAX_COORDINATE = 1.0e7
MAX_SPHERES = 1 << 21
# first_hits=auto weighs rasterised first hits against the traversal up to this many spheres (past it the
# quads' fragments, which grow with n, have always cost more: docs/RESULTS.md, "Peers").
FIRST_HITS_AUTO_MAX_SPHERES = 65536
# … and first_hits=tiles lists at most this many (tile, sphere) pairs (32 bytes each on the GPU, a few
# times that while they are sorted): past it a frame traces, so no scene of spheres that each cover much
# of the frame makes the host sort billions of entries.
MAX_TILE_PAIRS = 1 << 22
# The cost model counts a mesh scene's ray tree on a coarse grid of its pixels (renderer/frame/prepare.py,
# sampled_level_rays): this many pixels on the grid's long side, in scenes of at most this many
# primitives (the reference tracer tests every one; past it, the model's ray tree of the materials alone).
RAY_TREE_SAMPLE_SIDE = 24
# A drag moves the camera a little each frame: the ray tree counted for a view of the same scene within
# this angle of the new one (its forward direction, degrees) and this share of its distance to the
# target (its position) stands for the new view's, so a preview does not count again (6-57 ms each).
RAY_TREE_REUSE_DEG = 5.0
RAY_TREE_REUSE_MOVE = 0.05
# Slices (renderer/frame/prepare.py band_rows, renderer/gl/frame.py): a band of rows is sized for the rows
# through the scene's box — the frame's per-pixel cost over the share of the image the box covers, down
# to MIN_BAND_COVERAGE — and grows from the measured time of the last at most to MAX_BAND_GROWTH × the
# first (band after band of cheap sky would otherwise reach the scene with a band of most of it).
MIN_BAND_COVERAGE = 0.1
MAX_BAND_GROWTH = 4
RAY_TREE_SAMPLE_MAX_PRIMITIVES = 1 << 14
MAX_PLANES = 8
MAX_LIGHTS = 8
MAX_MATERIALS = 256
MAX_MOTIONS = 1024
MAX_LIGHT_INTENSITY = 1e3  # per RGB channel
MAX_EMISSION = 1e6  # radiance per RGB channel (materials' emission, the environment)
MAX_SHININESS = 1e4  # Phong exponent
MAX_IOR = 10.0  # refraction index
MAX_MUSEUM_MOVING = MAX_SPHERES - 1024  # the Museum's moving spheres: room for its static room
# Triangle meshes (docs/FORMATS.md, "Meshes"). A tree indexes spheres then triangles: with
# MAX_SPHERES + MAX_TRIANGLES < 2^22 every primitive index fits the BIH's 30-bit child
# index with room to spare, and a scene's arrays stay under ~100 MiB (72 B per triangle
# for its world-space corners, as many again for smooth normals).
MAX_TRIANGLES = 1 << 20  # per scene, all meshes together
MAX_MESH_VERTICES = 1 << 20  # per mesh
MAX_MESHES = 256  # per scene
# Analytic shapes (docs/FORMATS.md, "Analytic shapes"): cylinders, cones, disks and tori together.
# Each is one 96-byte record; with MAX_SPHERES + MAX_TRIANGLES + MAX_SHAPES < 2^22 a tree index
# over all three still fits the BIH's child index, as above.
MAX_SHAPES = 1 << 16  # per scene

# ---- model files ---------------------------------------------------------------------------
# renderer/io/model_guard.py checks a model file's own numbers (counts, lengths, the node tree)
# against these before a parser allocates what they ask for: a 250-byte glTF may claim 30
# million vertices, a 2 MB GLB a chain of 100,000 nodes (the parser's cost grows with the
# square of the depth). Each bound is far above what a model of MAX_TRIANGLES needs.
MAX_MODEL_NODES = 16_384  # glTF nodes (a flat scene of this many parses in ~0.6 s)
MAX_MODEL_NODE_DEPTH = 256  # glTF node-tree levels (the root counts as 1)
# A model's parts (glTF: primitives × the nodes that place them): each becomes a mesh before a scene
# joins those of one material, ~60 µs apiece in the service's own process, outside the parse's deadline.
MAX_MODEL_PARTS = 16_384
MAX_ACCESSOR_COUNT = 3 * MAX_TRIANGLES  # glTF elements of one accessor (the indices of MAX_TRIANGLES)
MAX_MODEL_ARRAY_BYTES = 256 << 20  # glTF: the bufferViews' bytes, and the accessors', each summed
MAX_BUFFERLESS_BYTES = 16 << 20  # glTF: accessors without a bufferView (zeros the file does not hold)
# Vertices a file may declare per vertex of MAX_MESH_VERTICES (before equal ones are merged: an
# STL stores three per triangle, a glTF repeats them per instance).
DECLARED_VERTEX_FACTOR = 3
MAX_PLY_HEADER_BYTES = 64 << 10  # a PLY header (text up to end_header)
# An OBJ's material libraries, all its .mtl files together (renderer/io/obj_model.py): a library of
# hundreds of materials is tens of KiB; each line is read in Python, ~1 s per 16 MiB here.
MAX_MTL_BYTES = 16 << 20
MAX_MODEL_NOTICES = 16  # lines saying what a model was read without (the rest counted in the last)
# A zipped model folder (renderer/io/model_archive.py): the central directory's numbers are checked
# against these before one byte is inflated, and inflating never yields more than an entry
# declares. Deflate reaches ~1,000:1 on zeros and 3-20:1 on models and images, so a ratio above
# MAX_ARCHIVE_RATIO in an entry of more than MAX_ARCHIVE_RATIO_FREE_BYTES is a bomb, not a model.
MAX_ARCHIVE_ENTRIES = 1024  # entries of a zip (directories and macOS's __MACOSX copies included)
MAX_ARCHIVE_ENTRY_BYTES = 128 << 20  # one entry, inflated (an OBJ of MAX_TRIANGLES is ~100 MiB of text)
MAX_ARCHIVE_BYTES = 256 << 20  # all the entries read, inflated together
MAX_ARCHIVE_RATIO = 100  # an entry's inflated bytes per compressed byte
MAX_ARCHIVE_RATIO_FREE_BYTES = 1 << 20  # entries up to this size may compress better (small text)
# Images inside a model (a zip's PNG/JPEG files, a GLB's or glTF's embedded ones): their declared
# size, read from the header, before anything decodes them. 8192² RGBA is 256 MiB decoded.
MAX_MODEL_IMAGE_SIDE = 8192  # pixels, either side
MAX_MODEL_IMAGE_PIXELS = 8192 * 8192  # width × height of one image

# ---- textures -------------------------------------------------------------------------------
# A scene's textures (renderer/materials/texture.py): each is kept at its size with its mip levels
# (4/3 of its texels), RGBA8. 8 × 2048² × 4 B × 4/3 ≈ 171 MiB is the most one scene holds.
MAX_TEXTURES = 64  # per scene
MAX_TEXTURE_SIDE = 4096  # pixels, either side: WebGL2 guarantees 2048 and most phones 4096
MAX_TEXTURE_TEXELS = 8 * 2048 * 2048  # all of a scene's textures together, level 0
MAX_TEXTURE_NAME = 256  # characters
# On the GPU the textures lie in one array (renderer/gpu/texture_layout.py), each in a square slot of its
# longer side rounded up to a power of two, the layers the largest slot's size. The array's level-0
# texels, the slots' unused ones included, stay within this: beyond it the largest textures are
# halved (a notice says which), 64 Mi texels × 4 B × 4/3 ≈ 341 MiB at the most.
MAX_TEXTURE_ARRAY_TEXELS = 16 * 2048 * 2048

# ---- environment images --------------------------------------------------------------------
# An equirectangular HDR image (renderer/materials/envmap.py): its declared size is checked against these
# before a texel is allocated. 4096 × 2048 float RGB is 96 MiB on the GPU (and as much again in
# the session store, where texels are kept as they are), the most one scene may ask for.
MAX_ENV_WIDTH = 4096
MAX_ENV_HEIGHT = 2048
MIN_ENV_SIDE = 2  # the bilinear lookup and the sampling patches need two rows and two columns
MAX_ENV_HEADER_BYTES = 64 << 10  # a .hdr header (text up to the resolution line), an .exr header
# An .exr file's channels: the library decodes every one (32 MiB each, FLOAT at the largest size),
# though R, G and B are all that is read.
MAX_ENV_CHANNELS = 16
MAX_ENV_SCALE = 1e6  # the image's radiance factor
MAX_ENV_ROTATION_DEG = 360.0  # about +y, either way

# ---- framing -------------------------------------------------------------------------------
# A screen's aspect (width / height) a demo scene's camera is framed for (renderer/scenes/scenarios.py):
# from a tall phone held upright (0.2) to a wide desktop window (5).
ASPECT_RANGE = (0.2, 5.0)

# ---- GPU data ------------------------------------------------------------------------------
DEFAULT_TEXTURE_WIDTH = 4096  # texture rows; WebGL2 guarantees 2048, most phones have 4096
MAX_DEVICE_TEXTURE_SIZE = 1 << 16  # the largest MAX_TEXTURE_SIZE a device may report (GPUs: ≤ 32,768)
MAX_DEVICE_ARRAY_LAYERS = 1 << 16  # the largest MAX_ARRAY_TEXTURE_LAYERS a device may report (GPUs: ≤ 8,192)
STENCIL_BITS = 8  # ray engines: one stencil bit per generation (≥ MAX_RECURSION_DEPTH)
# Compiled shader programs one renderer keeps (renderer/gl/programs.py), least recently used out:
# about 3 MiB resident each on llvmpipe, so ~100 MiB at most; a frame needs 1-3 of the tracer's
# (variant, background, first hits) or up to ~12 of a ray engine's passes.
MAX_PROGRAMS = 32

assert STENCIL_BITS >= MAX_RECURSION_DEPTH
