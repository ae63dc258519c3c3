#!/usr/bin/env python3
"""VTK's CPU ray caster (vtkFixedPointVolumeRayCastMapper) on a raw u8 or i16 volume, framed as voxcube frames it.

voxcube's experiments run this with the virtualenv `setup.sh` makes; it is the yardstick's side of
`voxcube bench` and `voxcube accuracy --frontier`. The camera: orthographic, looking at the volume's
centre from the direction (sin az cos el, sin el, cos az cos el), +Y up, `--span` world units across
the image; trilinear interpolation, sample distance `--dt` in cell edges, a headlight, Phong shading
with `--shading ambient,diffuse,specular,power`.
  --mode surface   : opacity a step at --iso (this mapper has no iso-surface mode), colour --color
  --mode composite : --transfer "value:r,g,b:opacity;..." (opacity per unit length, as voxcube's)
Prints one JSON line: the median and least seconds of --reps renders after a first one; --png writes
the last image.
"""
import argparse, json, os, time

ap = argparse.ArgumentParser()
ap.add_argument("--raw", required=True, help="samples of --type, X fastest, no header, little-endian")
ap.add_argument("--type", choices=["u8", "i16"], default="u8")
ap.add_argument("--dims", type=int, nargs=3, default=[97, 97, 116])
ap.add_argument("--mode", choices=["surface", "composite"], default="surface")
ap.add_argument("--iso", type=float, default=50.0)
ap.add_argument("--color", type=float, nargs=3, default=[0.95, 0.78, 0.45])
ap.add_argument("--transfer", default="10:0.2,0.3,0.8:0.0;60:0.9,0.7,0.3:0.15;200:1.0,0.2,0.1:0.8")
ap.add_argument("--shading", default="0.2,0.7,0.3,24")
ap.add_argument("--size", type=int, nargs=2, default=[350, 250])
ap.add_argument("--span", "--width", type=float, default=175.0, help="world units across the image")
ap.add_argument("--az", type=float, default=45.0)
ap.add_argument("--el", type=float, default=0.0)
ap.add_argument("--dt", type=float, default=0.5)
ap.add_argument("--threads", type=int, default=2)
ap.add_argument("--reps", type=int, default=7)
ap.add_argument("--png", default=None)
a = ap.parse_args()
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkOSOpenGLRenderWindow")

import numpy as np
import vtk
from vtk.util import numpy_support as ns

vtk.vtkObject.GlobalWarningDisplayOff()
vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(a.threads)
vtk.vtkMultiThreader.SetGlobalDefaultNumberOfThreads(a.threads)
nx, ny, nz = a.dims
samples = np.fromfile(a.raw, dtype={"u8": np.uint8, "i16": np.dtype("<i2")}[a.type])
if samples.size < nx * ny * nz:
    raise SystemExit(f"{a.raw}: {samples.size} samples, {nx}x{ny}x{nz} expected")
grid = vtk.vtkImageData()
grid.SetDimensions(nx, ny, nz)
grid.SetSpacing(1, 1, 1)
grid.SetOrigin(0, 0, 0)
scalars = ns.numpy_to_vtk(np.ascontiguousarray(samples[: nx * ny * nz]), deep=True)
scalars.SetName("s")
grid.GetPointData().SetScalars(scalars)

color, opacity = vtk.vtkColorTransferFunction(), vtk.vtkPiecewiseFunction()
if a.mode == "surface":
    color.AddRGBPoint(0, *a.color)
    color.AddRGBPoint(255, *a.color)
    for value, o in [(0, 0.0), (a.iso - 1e-3, 0.0), (a.iso, 1.0), (255, 1.0)]:
        opacity.AddPoint(value, o)
else:
    for point in a.transfer.split(";"):
        value, rgb, o = point.split(":")
        color.AddRGBPoint(float(value), *map(float, rgb.split(",")))
        opacity.AddPoint(float(value), float(o))
ambient, diffuse, specular, power = map(float, a.shading.split(","))
prop = vtk.vtkVolumeProperty()
prop.SetColor(color)
prop.SetScalarOpacity(opacity)
prop.SetScalarOpacityUnitDistance(1.0)
prop.SetInterpolationTypeToLinear()
prop.ShadeOn()
prop.SetAmbient(ambient)
prop.SetDiffuse(diffuse)
prop.SetSpecular(specular)
prop.SetSpecularPower(power)

mapper = vtk.vtkFixedPointVolumeRayCastMapper()
mapper.SetNumberOfThreads(a.threads)
for set_distance in (mapper.SetImageSampleDistance, mapper.SetMinimumImageSampleDistance,
                     mapper.SetMaximumImageSampleDistance):
    set_distance(1.0)
mapper.SetInputData(grid)
mapper.AutoAdjustSampleDistancesOff()
mapper.LockSampleDistanceToInputSpacingOff()
mapper.SetSampleDistance(a.dt)
mapper.SetInteractiveSampleDistance(a.dt)
mapper.SetBlendModeToComposite()
volume = vtk.vtkVolume()
volume.SetMapper(mapper)
volume.SetProperty(prop)
renderer = vtk.vtkRenderer()
renderer.SetBackground(0, 0, 0)
renderer.AddVolume(volume)
window = vtk.vtkRenderWindow()
window.SetOffScreenRendering(1)
window.SetSize(*a.size)
window.SetMultiSamples(0)
window.AddRenderer(renderer)

centre = np.array([(nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2])
az, el = np.radians(a.az), np.radians(a.el)
toward_eye = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
radius = np.linalg.norm([nx - 1, ny - 1, nz - 1]) / 2
camera = renderer.GetActiveCamera()
camera.ParallelProjectionOn()
camera.SetFocalPoint(*centre)
camera.SetPosition(*(centre + 2 * radius * toward_eye))
camera.SetViewUp(0, 1, 0)
camera.SetParallelScale(a.span * a.size[1] / a.size[0] / 2)
camera.SetClippingRange(0.1, 4 * radius + 1)
renderer.LightFollowCameraOn()


def render():
    window.Render()
    window.GetRGBACharPixelData(0, 0, 0, 0, 0)


render()
seconds = []
for _ in range(max(a.reps, 1)):
    volume.Modified()
    start = time.perf_counter()
    render()
    seconds.append(time.perf_counter() - start)
if a.png:
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.SetInputBufferTypeToRGB()
    grab.ReadFrontBufferOff()
    grab.Update()
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(a.png)
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()
print(json.dumps({"vtk": vtk.vtkVersion.GetVTKVersion(), "mode": a.mode, "threads": a.threads,
                  "median_s": round(float(np.median(seconds)), 5), "min_s": round(min(seconds), 5)}))
