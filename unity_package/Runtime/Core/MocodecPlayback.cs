using System;
using System.Collections.Generic;

namespace Mocodec
{
    /// <summary>
    /// One playing clip on one rig, with no engine type in it: time (speed, loop, clamped end),
    /// sampling into a buffer of its own, retargeting onto the rig (<see cref="MocodecRetarget"/>)
    /// and the conversion to the engine's space. What the Unity player and the Playables job
    /// share, tested under mono. <see cref="Evaluate"/> allocates nothing.
    /// </summary>
    public sealed class MocodecPlayback : IDisposable
    {
        readonly MocodecContext _context;
        readonly MocodecRetarget _retarget;
        readonly MocodecTransform[] _pose;
        readonly MocodecTransform[] _rigPose;
        readonly bool _mirror;
        readonly int _clip;
        readonly float _duration;

        public float Time;
        /// <summary>Playback rate; negative plays backwards.</summary>
        public float Speed = 1f;
        public bool Loop = true;
        /// <summary>Contact IK (<see cref="SampleFlags.Contacts"/>), on by default: a no-op for
        /// assets without contacts.</summary>
        public bool Contacts = true;
        public bool Playing = true;

        /// <param name="rig">The rig in the engine's space: left-handed (Unity) when
        /// <paramref name="leftHanded"/>, else right-handed like the asset.</param>
        /// <param name="settings">UnitScale is rig units per asset unit
        /// (<see cref="MocodecSpace.MetresPerUnit"/> for a rig in metres).</param>
        public MocodecPlayback(MocodecAsset asset, int clip, RigBone[] rig, bool leftHanded, RetargetSettings settings,
                               IDictionary<string, string> pairs = null)
        {
            if (asset == null)
                throw new ArgumentNullException("asset");
            ClipInfo info = asset.GetClipInfo(clip);
            _clip = clip;
            _duration = info.Duration;
            _mirror = leftHanded;
            _retarget = new MocodecRetarget(asset, info.Skeleton, leftHanded ? MocodecSpace.MirrorX(rig) : rig, pairs, settings);
            _context = asset.CreateContext();
            _pose = new MocodecTransform[info.NodeCount];
            _rigPose = new MocodecTransform[_retarget.BoneCount];
        }

        public float Duration { get { return _duration; } }
        public int Clip { get { return _clip; } }
        public MocodecRetarget Retarget { get { return _retarget; } }

        /// <summary>The rig's local transforms of the last <see cref="Evaluate"/>, in the engine's
        /// space, one per rig bone (bones not driven by the asset stay at their rest).</summary>
        public MocodecTransform[] RigPose { get { return _rigPose; } }

        /// <summary>Moves time by <paramref name="deltaSeconds"/> x speed when playing: a looping
        /// clip wraps (time stays small, so float time keeps its precision), another stops at
        /// its end (or start, played backwards).</summary>
        public void Advance(float deltaSeconds)
        {
            if (!Playing)
                return;
            Time += deltaSeconds * Speed;
            if (Loop)
            {
                float d = _duration > 0f ? _duration : 1f;
                Time -= (float)Math.Floor(Time / d) * d;
            }
            else if ((Speed > 0f && Time >= _duration) || (Speed < 0f && Time <= 0f))
            {
                Time = Math.Max(0f, Math.Min(Time, _duration));
                Playing = false;
            }
        }

        /// <summary>One engine frame for a component whose serialized fields hold the time and
        /// settings: takes them, advances by <paramref name="deltaSeconds"/> (0: pose at
        /// <paramref name="time"/> only), samples into <see cref="RigPose"/>, and returns the new
        /// time for the component to keep.</summary>
        public float Tick(float time, float speed, bool loop, bool contacts, float deltaSeconds)
        {
            Time = time;
            Speed = speed;
            Loop = loop;
            Contacts = contacts;
            Advance(deltaSeconds);
            Evaluate();
            return Time;
        }

        /// <summary>Samples the clip at <see cref="Time"/> and retargets it into <see cref="RigPose"/>.</summary>
        public void Evaluate()
        {
            SampleFlags flags = (Loop ? SampleFlags.Loop : SampleFlags.None) | (Contacts ? SampleFlags.Contacts : SampleFlags.None);
            _context.Sample(_clip, Time, _pose, flags);
            _retarget.Apply(_pose, _rigPose);
            if (_mirror)
                MocodecSpace.MirrorX(_rigPose, _rigPose.Length);
        }

        public void Dispose()
        {
            _context.Dispose();
            _retarget.Dispose();
        }
    }
}
