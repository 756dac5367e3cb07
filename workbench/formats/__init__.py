"""Readers and writers of file formats: C3D marker takes, Live Link Face CSVs, weight curves, OBJ meshes and glTF,
with the plausibility checks every reader applies."""
