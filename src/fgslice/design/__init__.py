"""Design input: the .vcad language, expressions, geometry and material nodes, meshes."""
