"""What the mesh scripts (make_biventricle.py, make_palm.py) share: a deterministic gmsh
session and the meshing settings (Delaunay, Netgen optimisation, MSH 4.1 ASCII)."""
import gmsh


def start(model_name):
    """Initialises gmsh quietly, single-threaded with a fixed seed (reproducible output)."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.model.add(model_name)
    return gmsh.model.occ


def mesh_and_write(out, size, min_fraction, curvature_points, before_write=None):
    """Meshes the synchronised model with linear tetrahedra of size in
    [min_fraction * size, size] and writes MSH 4.1 ASCII; returns the tetrahedron count.
    before_write(), if given, runs between meshing and writing (to regroup elements)."""
    gmsh.option.setNumber("Mesh.MeshSizeMin", min_fraction * size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", curvature_points)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay
    gmsh.option.setNumber("Mesh.Optimize", 1)
    gmsh.option.setNumber("Mesh.OptimizeNetgen", 1)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.model.mesh.generate(3)
    if before_write:
        before_write()
    gmsh.write(out)
    _, tags, _ = gmsh.model.mesh.getElements(3)
    return sum(len(t) for t in tags)
