"""Screen-space reflection kernels: rays from mirror pixels (rays.py), marches over the
depth buffer (march.py: linear and McGuire & Mara's DDA; hiz.py: a min-depth pyramid),
pixel projection across mirror planes (project.py) and the shared resolve (resolve.py)."""
