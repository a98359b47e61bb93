// Internal to core/scene: whole-file checks that run before any mesh is read — which
// extensions the file requires or uses, and that every bufferView lies inside its
// buffer (so accessor checks only need to look at their own bufferView).
#pragma once

#include "core/scene/gltf_context.h"

namespace lightlink::scene::gltf {

// Extensions lightlink implements; anything else in extensionsRequired is kUnsupported.
bool isSupportedExtension(std::string_view name);

Status validateExtensions(const Context& ctx);
Status validateBufferViews(const Context& ctx);

}  // namespace lightlink::scene::gltf
