// The light from outside the scene where no object is (radiosity.physics.environment):
// the pixel's ray (as radiosity.files.camera.Camera.pixel_rays makes it) turned into
// the environment's frame, its latitude-longitude (u, v) in Mitsuba 3's convention, the
// map read bilinearly: column i at u = (i + 0.5) / W, repeating (GL_REPEAT in s), row j
// at v = j / (H - 1) (t = (v (H - 1) + 0.5) / H, clamped), times its scale.
uniform sampler2D environment;
uniform mat3 env_rotation;   // world from environment
uniform float env_scale;
uniform vec3 cam_right;
uniform vec3 cam_up;
uniform vec3 cam_forward;
uniform vec2 cam_extent;     // (tan(fov / 2) * width / height, tan(fov / 2))
uniform vec2 viewport;
out vec4 f_colour;
void main() {
    vec2 ndc = gl_FragCoord.xy / viewport * 2.0 - 1.0;
    vec3 d = normalize(cam_forward + ndc.x * cam_extent.x * cam_right + ndc.y * cam_extent.y * cam_up);
    vec3 l = transpose(env_rotation) * d;
    float u = atan(l.x, -l.z) * 0.15915494309189535;
    if (u < 0.0) u += 1.0;
    float v = acos(clamp(l.y, -1.0, 1.0)) * 0.3183098861837907;
    float rows = float(textureSize(environment, 0).y);
    f_colour = vec4(texture(environment, vec2(u, (v * (rows - 1.0) + 0.5) / rows)).rgb * env_scale, 1.0);
}
