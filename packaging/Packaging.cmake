# CPack: `cpack -G DEB` in a build folder makes a Debian package, `residue`, of what `install` puts in place for the
# `residue` component: the viewer and residue-cli (bin/), the shipped data (share/residue: models, the OCIO config,
# icons), the desktop entry and the hicolor icons. packaging/test_package.sh builds it, unpacks it and runs it.
#
# Only the `residue` component is packaged (CPACK_COMPONENTS_ALL below). residue-train's install rule carries no
# component, so it stays out of the package: the trainer is a developer tool and would make the package depend on
# libtorch (hundreds of MB) for users who only denoise and view. An install() meant for the package must say
# `COMPONENT residue`.
#
# The programs find their data relative to themselves (core/util/resources.cpp: <exe dir>/../share/residue), so
# BINDIR and DATADIR must stay one level below the prefix (the GNUInstallDirs defaults, bin and share).
include(GNUInstallDirs)

# Shipped data: everything in resources/ but the example renders (the test data of the README's first command).
install(DIRECTORY ${PROJECT_SOURCE_DIR}/resources/ DESTINATION ${CMAKE_INSTALL_DATADIR}/residue
        COMPONENT residue
        PATTERN "examples" EXCLUDE)

# Desktop integration, with the viewer only.
if(TARGET residue)
  install(FILES ${PROJECT_SOURCE_DIR}/packaging/residue.desktop
          DESTINATION ${CMAKE_INSTALL_DATADIR}/applications COMPONENT residue)
  foreach(_size 16 32 48 64 128 256)
    install(FILES ${PROJECT_SOURCE_DIR}/resources/icons/hicolor/${_size}x${_size}/apps/residue.png
            DESTINATION ${CMAKE_INSTALL_DATADIR}/icons/hicolor/${_size}x${_size}/apps COMPONENT residue)
  endforeach()
  install(FILES ${PROJECT_SOURCE_DIR}/resources/icons/residue.svg
          DESTINATION ${CMAKE_INSTALL_DATADIR}/icons/hicolor/scalable/apps COMPONENT residue)
endif()

set(RESIDUE_PACKAGE_MAINTAINER "Residue developers" CACHE STRING
    "Maintainer field of the Debian package (Debian wants \"Name <email>\")")

set(CPACK_PACKAGE_NAME "residue")
set(CPACK_PACKAGE_VENDOR "Residue")
set(CPACK_PACKAGE_VERSION "${PROJECT_VERSION}")
set(CPACK_PACKAGE_CONTACT "${RESIDUE_PACKAGE_MAINTAINER}")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Monte Carlo render denoiser and viewer")
set(CPACK_STRIP_FILES ON)

# One package made of the listed components (residue-train's unnamed component is left out, see above).
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_GROUPING ALL_COMPONENTS_IN_ONE)
set(CPACK_COMPONENTS_ALL residue)

set(CPACK_DEBIAN_PACKAGE_NAME "residue")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)          # residue_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_SECTION "graphics")
set(CPACK_DEBIAN_PACKAGE_PRIORITY "optional")
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${RESIDUE_PACKAGE_MAINTAINER}")
# The synopsis line is CPACK_PACKAGE_DESCRIPTION_SUMMARY; this is the extended description under it.
if(TARGET residue)
  set(_residue_programs "the Qt6 viewer residue, the command-line tool residue-cli")
else()
  set(_residue_programs "the command-line tool residue-cli")
endif()
if(TARGET residue_python)
  set(_residue_python ", and the Python module (import residue)")
  # The module needs Debian's python3 and NumPy to import; the programs do not, so they are only suggested.
  set(CPACK_DEBIAN_PACKAGE_SUGGESTS "python3, python3-numpy")
endif()
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
    "Residue denoises Monte Carlo renders (Blender Cycles, Arnold, RenderMan, V-Ray and plain multilayer EXRs)
with a direct residual network and measures how good the result is (against a
reference: MSE, relMSE, PSNR, SSIM, HDR-FLIP). This package holds ${_residue_programs}, the shipped models and an
OCIO config${_residue_python}.")
# dpkg-shlibdeps computes Depends from the binaries' shared libraries (Qt6, OpenImageIO, OpenColorIO, TBB, oneDNN...)
# and appends them to the ones given here. The viewer cannot start without a Qt platform plugin (xcb, wayland),
# which libqt6gui6 only recommends.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
if(TARGET residue)
  set(CPACK_DEBIAN_PACKAGE_DEPENDS "qt6-qpa-plugins")
endif()
# The payload is a few MB; gzip keeps `cpack -G DEB` quick (packaging/test_package.sh runs it as a test).
set(CPACK_DEBIAN_COMPRESSION_TYPE "gzip")

include(CPack)
