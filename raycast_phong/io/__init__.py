"""Files: every format the package reads or writes, and nothing of the renderer.

scene_file (TOML/JSON syntax), scene_toml (a Scene written back as a scene file, tomli-w), meshes/ (the mesh file
formats, one module each behind one interface, and their registry), image_io (the only OpenImageIO importer),
textures (colour maps), encoding (8-bit, sRGB), atomic (the checked, atomic writer every output goes through),
files (open_regular, file versions), system (available memory).
"""
