# Install and export rules: what another CMake project gets from `find_package(lightlink)`
# (docs/clients.md "Using the client library from CMake"). Only the client library and what
# it links are exported (lightlink::client, ::proto, ::lights, ::common); the baker's modules
# stay in the build, so a consumer never needs Embree, OpenMesh, TBB, assimp or OpenEXR.
# Everything goes into the `lightlink_client` install component.
include(CMakePackageConfigHelpers)

set(LIGHTLINK_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/lightlink")
set(LIGHTLINK_INSTALL_INCLUDEDIR "${CMAKE_INSTALL_INCLUDEDIR}/lightlink")

set_target_properties(lightlink_client PROPERTIES EXPORT_NAME client)
set_target_properties(lightlink_proto PROPERTIES EXPORT_NAME proto)
set_target_properties(lightlink_lights PROPERTIES EXPORT_NAME lights)
set_target_properties(lightlink_common PROPERTIES EXPORT_NAME common)
install(TARGETS lightlink_client lightlink_proto lightlink_lights lightlink_common
        EXPORT lightlinkTargets
        ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}" COMPONENT lightlink_client)

# Headers keep their source-tree paths ("clients/client/client.h", "proto/lightlink.pb.h"),
# so installed headers include each other exactly as they do in the build.
install(DIRECTORY "${PROJECT_SOURCE_DIR}/core/common" "${PROJECT_SOURCE_DIR}/core/lights"
        DESTINATION "${LIGHTLINK_INSTALL_INCLUDEDIR}/core" COMPONENT lightlink_client
        FILES_MATCHING PATTERN "*.h")
install(FILES clients/client/client.h clients/client/light_update.h clients/client/local_daemon.h
              clients/client/session.h clients/client/shared_result.h
              clients/client/textures.h
        DESTINATION "${LIGHTLINK_INSTALL_INCLUDEDIR}/clients/client" COMPONENT lightlink_client)
install(FILES proto/shared_result_format.h proto/lightlink.proto
              "${PROJECT_BINARY_DIR}/proto/lightlink.pb.h" "${PROJECT_BINARY_DIR}/proto/lightlink.grpc.pb.h"
        DESTINATION "${LIGHTLINK_INSTALL_INCLUDEDIR}/proto" COMPONENT lightlink_client)

install(EXPORT lightlinkTargets NAMESPACE lightlink:: DESTINATION "${LIGHTLINK_INSTALL_CMAKEDIR}"
        COMPONENT lightlink_client)
configure_package_config_file(cmake/lightlinkConfig.cmake.in "${PROJECT_BINARY_DIR}/lightlinkConfig.cmake"
                              INSTALL_DESTINATION "${LIGHTLINK_INSTALL_CMAKEDIR}")
# 0.x: a minor version may change the API.
write_basic_package_version_file("${PROJECT_BINARY_DIR}/lightlinkConfigVersion.cmake"
                                 COMPATIBILITY SameMinorVersion)
install(FILES "${PROJECT_BINARY_DIR}/lightlinkConfig.cmake" "${PROJECT_BINARY_DIR}/lightlinkConfigVersion.cmake"
        DESTINATION "${LIGHTLINK_INSTALL_CMAKEDIR}" COMPONENT lightlink_client)
