"""horsemocap: saddle motion analysis of horses with a 3-camera vision system.

A Python reproduction of G. Dogan, "Development of a 3-camera vision system
and the saddle motion analysis of horses via this system", MSc thesis, METU,
2009. One module per pipeline step; see ``notebooks/00_start_here.ipynb``.
"""
__version__ = "0.1.0"
