#pragma once
/// \file synth.hpp
/// The exact renderer: synthetic omni-image and panorama sequences with exact ground truth.
/// It is the referee for every sign and formula of the project (DESIGN.md sections 2, 3):
/// each output pixel looks exactly along the bearing that the calibration assigns to it.
///
/// The renderer and its inputs, one header each (this one includes them all):
///   scene.hpp               the photo on a sphere or a room, the people walking in it
///   equirect_from_omni.hpp  a scene texture made from a real omni image
///   renderer.hpp            Renderer, FrameTiming, trajectory interpolation
///   occluder.hpp            what the robot sees of itself
///   vignetting.hpp          the lens' brightness falloff
///   degrade.hpp             sensor blur, exposure, noise
///   motion.hpp              motion scripts and the trajectories they generate
///   gyro.hpp                a gyro on the camera, driven by the exact motion
///   dataset_writer.hpp      frames, timestamps and ground truth as a dataset directory
///
/// Camera and world effects, each exact against the definition its declaration states:
/// rolling shutter and exposure time (motion blur) in FrameTiming, people walking around
/// the robot in Walkers, track vibration in Vibration, vignetting in Vignetting, sensor
/// blur, noise, exposure jitter and auto-exposure steps in DegradeOptions.
///
/// Example: a 5-frame yaw sequence of omni images, written as a dataset (compiled and run by
/// tests/synth/header_example_test.cpp)
/// ```
///   auto scene = synth::Scene::load("indoor.jpg", synth::SceneKind::kSphere);
///   synth::Renderer renderer(scene, Calibration{}, {});
///   auto script = synth::MotionScript::preset("yaw");
///   script.frames = 5;
///   auto poses = synth::generateTrajectory(script);
///   synth::DatasetWriter writer("out", Calibration{}, 0);
///   for (std::size_t k = 0; k < poses.size(); ++k)
///     writer.addFrame(synth::degrade(renderer.render(poses[k].pose), {}, k), poses[k]);
///   writer.finish();
/// ```

#include "omnipose/synth/dataset_writer.hpp"
#include "omnipose/synth/degrade.hpp"
#include "omnipose/synth/equirect_from_omni.hpp"
#include "omnipose/synth/gyro.hpp"
#include "omnipose/synth/motion.hpp"
#include "omnipose/synth/occluder.hpp"
#include "omnipose/synth/renderer.hpp"
#include "omnipose/synth/scene.hpp"
#include "omnipose/synth/vignetting.hpp"
