"""The optional C extension (topgimbal._speedups._ctop), built from libtopgimbal's sources.

Everything else is declared in pyproject.toml. `optional=True`: where no C compiler is found the
build goes on without it and topgimbal runs on pure Python (topgimbal.speedups_enabled() says so).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "topgimbal._speedups._ctop",
            sources=["src/topgimbal/_speedups/_ctop.c", "c/src/tg_scan.c", "c/src/tg_codec.c"],
            include_dirs=["c/include", "c/generated"],
            depends=["c/include/topgimbal.h", "c/src/tg_internal.h", "c/generated/tg_limits.h"],
            extra_compile_args=["-O2"],
            optional=True,
        )
    ]
)
