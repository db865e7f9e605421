#version 450
//
// Adapted from SAPIEN 3.0.3's "trivial" camera shader pack (sapien/vulkan_shader/trivial):
// the descriptor sets below are the interface SAPIEN's shader-pack parser requires.
// Copyright 2025 Hillbot Inc.
// Copyright 2020-2024 UCSD SU Lab
// Licensed under the Apache License, Version 2.0: http://www.apache.org/licenses/LICENSE-2.0
//
// Draws the geometry in view; the fragment shader ignores it.
#extension GL_ARB_separate_shader_objects : enable
#extension GL_ARB_shading_language_420pack : enable

layout(set = 0, binding = 0) uniform CameraBuffer {
  mat4 viewMatrix;
  mat4 projectionMatrix;
  mat4 viewMatrixInverse;
  mat4 projectionMatrixInverse;
  float width;
  float height;
} cameraBuffer;

layout(set = 1, binding = 0) uniform ObjectTransformBuffer {
  mat4 modelMatrix;
} objectTransformBuffer;

layout(set = 1, binding = 1) uniform ObjectDataBuffer {
  uvec4 segmentation;
  float transparency;
  int shadeFlat;
} objectDataBuffer;

layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in vec2 uv;
layout(location = 3) in vec3 tangent;
layout(location = 4) in vec3 bitangent;

void main() {
  gl_Position = cameraBuffer.projectionMatrix * cameraBuffer.viewMatrix
      * objectTransformBuffer.modelMatrix * vec4(position, 1);
}
