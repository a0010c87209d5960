"""rollability_ros: design and validate passive self-righting profiles for small wheeled robots.

The generated interfaces (``rollability_ros.msg``, ``.srv``, ``.action``) are installed by CMake into the
install prefix, while the hand-written modules may live in a source checkout; ``extend_path`` lets one
``import rollability_ros`` see both halves whichever of them Python finds first.
"""
from pkgutil import extend_path

__path__ = extend_path(__path__, __name__)
__version__ = "0.1.0"
