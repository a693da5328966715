"""Files: the only OpenImageIO importer (image_io) and the checked, atomic writer every output goes through."""
