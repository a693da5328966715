"""The pipeline: one module per stage, from a scene file to the image; imports nothing from io/ or tools/."""
