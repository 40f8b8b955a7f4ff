# CPack: `cpack -G DEB` in a build folder makes a Debian package of what `install` puts in place.
set(CPACK_PACKAGE_NAME "residue")
set(CPACK_PACKAGE_VENDOR "Residue")
set(CPACK_PACKAGE_CONTACT "Residue developers")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${PROJECT_DESCRIPTION}")
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/resources/ DESTINATION share/residue
        PATTERN "examples" EXCLUDE)
include(CPack)
