"""Files: every format the package reads or writes, and nothing of the renderer.

scene_file (TOML/JSON syntax), scene_toml (a Scene written back as a scene file, tomli-w), mesh_file (trimesh,
.mtl, glTF materials), mesh_header (triangle counts before a read), image_io (the only OpenImageIO importer),
encoding (8-bit, sRGB), atomic (the checked, atomic writer every output goes through), files (open_regular, the
file-version cache), system (available memory).
"""
