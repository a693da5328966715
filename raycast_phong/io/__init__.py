"""Files: every format the package reads or writes, and nothing of the renderer.

scene_file (TOML/JSON syntax), scene_toml (a Scene written back as a scene file, tomli-w), mesh_source (one
object per mesh file: what the stages before the geometry want of it, read once), mesh_file (the geometry through
trimesh) with the formats' own parts: mtl, gltf, obj, stl, mesh_content, materials; mesh_header (triangle counts
before a read), image_io (the only OpenImageIO importer),
encoding (8-bit, sRGB), atomic (the checked, atomic writer every output goes through), files (open_regular, the
file-version cache), system (available memory).
"""
