#version 450
//
// Adapted from SAPIEN 3.0.3's "trivial" camera shader pack (sapien/vulkan_shader/trivial):
// the descriptor sets below are the interface SAPIEN's shader-pack parser requires.
// Copyright 2025 Hillbot Inc.
// Copyright 2020-2024 UCSD SU Lab
// Licensed under the Apache License, Version 2.0: http://www.apache.org/licenses/LICENSE-2.0
//
// Each pixel gets the texel of SAPIEN's BRDF lookup table at its own coordinates, unfiltered
// (maniskill_tidy/sim/brdf_lut.py reads the table back from the "Lut" picture).

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

layout(set = 2, binding = 0) uniform MaterialBuffer {
  vec4 emission;
  vec4 baseColor;
  float fresnel;
  float roughness;
  float metallic;
  float transmission;
  float ior;
  float transmissionRoughness;
  int textureMask;
  int padding1;
  vec4 textureTransforms[6];
} materialBuffer;

struct PointLight {
  vec4 position;
  vec4 emission;
};

struct DirectionalLight {
  vec4 direction;
  vec4 emission;
};

struct SpotLight {
  vec4 position;
  vec4 direction;
  vec4 emission;
};

layout(set = 3, binding = 0) uniform SceneBuffer {
  vec4 ambientLight;
  DirectionalLight directionalLights[3];
  SpotLight spotLights[10];
  PointLight pointLights[10];
  SpotLight texturedLights[1];
} sceneBuffer;
layout(set = 3, binding = 1) uniform sampler2D samplerBRDFLUT;

layout(location = 0) out vec4 outLut;

void main() {
  outLut = texelFetch(samplerBRDFLUT, ivec2(gl_FragCoord.xy), 0);
}
